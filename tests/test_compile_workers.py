"""A first start compiles a controller's kernels in worker processes (wbc.runtime.kernels._pool).

On a cold numba cache the kernels a controller uses are handed to worker processes that
compile them into the shared cache while the controller's process compiles the others; the
process reads the workers' machine code from the cache. The ticks must be those of a process
that compiled everything itself, and a worker that fails or dies must cost nothing but time.
"""

import json
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import NEUTRAL, child_environment
from wbc.runtime.kernels import _pool
from wbc.runtime.kernels._pool import MAX_WORKERS, WORKERS_VARIABLE, CompilePool

_FIRST_START = """
    import json
    import numpy as np
    import wbc
    from wbc.runtime import kernels
    robot = wbc.load_robot("youbot")
    ee = wbc.FrameTask("ee", position_cost=1.0, orientation_cost=0.5)
    controller = wbc.Controller(robot, tasks=[ee, wbc.PostureTask(cost=1e-3)],
                                constraints=[wbc.JointPositionLimits(), wbc.JointVelocityLimits()])
    workers = kernels._workers
    compiled_by_workers = [] if workers is None else sorted(job for job, ok in workers._finished.items() if ok)
    q = np.array([0, 0, 0, 0, 0.5, 1.0, 1.2, 0.0])
    target = robot.frame_pose(q, "ee")
    commands = []
    for k in range(20):
        target[:3, 3] += [0.002, 0.001, -0.001]
        ee.set_target(target)
        v = controller.step(q)
        commands.append(v.tolist())
        q = robot.integrate(q, v, 0.01)
    print(json.dumps(dict(workers=compiled_by_workers, commands=commands)))
"""


def _first_start(cache, workers: int) -> dict:
    """The youBot controller's first start on the empty numba cache ``cache`` with ``workers`` compile workers."""
    result = subprocess.run([sys.executable, "-c", textwrap.dedent(_FIRST_START)], capture_output=True, text=True,
                            cwd=NEUTRAL, timeout=600,
                            env={**child_environment(), "NUMBA_CACHE_DIR": str(cache), WORKERS_VARIABLE: str(workers)})
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_a_first_start_compiles_in_a_worker_and_ticks_as_when_compiled_in_process(tmp_path):
    with_worker = _first_start(tmp_path / "with", 1)
    alone = _first_start(tmp_path / "alone", 0)
    assert with_worker["workers"], "no kernel was compiled by the worker"
    assert any(job.startswith("op ") for job in with_worker["workers"])
    assert alone["workers"] == []
    np.testing.assert_allclose(with_worker["commands"], alone["commands"], rtol=0, atol=1e-12)
    assert np.abs(alone["commands"]).max() > 1e-3  # the controller moved: the comparison says something


def test_a_job_no_worker_started_is_the_callers():
    pool = CompilePool(0)
    pool.submit(["kernel has_nan", "kernel has_nan", "op HAS_NAN"])
    assert pool.take("kernel has_nan")
    assert not pool.take("kernel has_nan")  # queued once, taken once
    assert not pool.wait("kernel has_nan")  # not compiled by a worker: the caller compiles it
    assert pool.take("op HAS_NAN")
    pool.close()


def test_a_job_a_worker_cannot_compile_or_dies_on_is_the_callers():
    pool = CompilePool(1)
    pool.submit(["op NO_SUCH_OP"])
    deadline = time.monotonic() + 120
    while "op NO_SUCH_OP" not in pool._finished and time.monotonic() < deadline:
        time.sleep(0.01)
    assert pool._finished.get("op NO_SUCH_OP") is False  # the worker answered "failed"
    assert not pool.wait("op NO_SUCH_OP")  # so the caller compiles it
    pool._processes[0].kill()
    pool._processes[0].wait()
    pool.submit(["kernel has_nan"])
    while "kernel has_nan" not in pool._finished and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not pool.wait("kernel has_nan")  # the dead worker's job: the caller compiles it, nothing hangs
    pool.close()


def test_a_worker_compiles_without_running_wbcs_top_level():
    """A worker imports wbc.runtime alone (its BOOTSTRAP skips wbc/__init__.py): no Pinocchio in
    its memory, yet it compiles a job (into the shared cache)."""
    pool = CompilePool(1)
    try:
        pool.submit(["kernel has_non_finite"])
        deadline = time.monotonic() + 120
        while "kernel has_non_finite" not in pool._finished and time.monotonic() < deadline:
            time.sleep(0.01)
        assert pool._finished.get("kernel has_non_finite") is True
        maps = (Path("/proc") / str(pool._processes[0].pid) / "maps").read_text()
        assert "numba" in maps  # (the check below reads the right process)
        assert "pinocchio" not in maps.lower()
    finally:
        pool.close()


@pytest.mark.parametrize(("idle_fraction", "cpus", "affinity", "expected"), [
    (0.5, 2, 2, 1),  # this process busy on one core, the other idle: one worker
    (0.2, 2, 2, 0),  # the other core mostly busy: none
    (0.02, 2, 2, 0),  # every core busy
    (0.75, 4, 4, 3),  # three idle cores of four
    (1.0, 8, 8, 3),  # at most MAX_WORKERS
    (0.75, 4, 2, 1),  # at most the cores this process may use, less its own
])
def test_worker_count_follows_the_cores_left_idle(monkeypatch, idle_fraction, cpus, affinity, expected):
    """Idle cores = idle share of the machine's CPU time since the import x CPUs (here a window
    of 1 s of 100-Hz jiffies per CPU), rounded, capped."""
    monkeypatch.delenv(WORKERS_VARIABLE, raising=False)
    start = (0.0, 0.0, 0.0)
    total = 100.0 * cpus
    monkeypatch.setattr(_pool, "_IMPORTED", start)
    monkeypatch.setattr(_pool, "cpu_times", lambda: (1.0, idle_fraction * total, total))
    monkeypatch.setattr(_pool.os, "cpu_count", lambda: cpus)
    monkeypatch.setattr(_pool.os, "sched_getaffinity", lambda pid: set(range(affinity)))
    assert _pool.worker_count() == expected
    assert MAX_WORKERS == 3


def test_worker_count_without_proc_stat_reads_the_load_average(monkeypatch):
    monkeypatch.delenv(WORKERS_VARIABLE, raising=False)
    monkeypatch.setattr(_pool, "cpu_times", lambda: None)
    monkeypatch.setattr(_pool.os, "sched_getaffinity", lambda pid: {0, 1, 2, 3})
    monkeypatch.setattr(_pool.os, "getloadavg", lambda: (1.2, 1.0, 1.0))
    assert _pool.worker_count() == 2  # 4 cores - this process - 1.2 busy = 1.8 idle
    monkeypatch.setattr(_pool.os, "getloadavg", lambda: (3.0, 1.0, 1.0))
    assert _pool.worker_count() == 0
    monkeypatch.setenv(WORKERS_VARIABLE, "2")
    assert _pool.worker_count() == 2  # the setting wins
    monkeypatch.setenv(WORKERS_VARIABLE, "many")
    assert _pool.worker_count() == 0


@pytest.mark.parametrize(("others_busy", "expected"), [
    (0.0, 1),  # nothing else ran: the early worker's core was idle, it stays
    (0.9, 0),  # another process kept the second core busy: dismissed
    (0.3, 1),  # rounded
])
def test_an_early_workers_own_time_counts_as_idle(monkeypatch, others_busy, expected):
    """Over 1 s on 2 CPUs (200 jiffies): this process busy 100, the early worker 60, the others
    ``others_busy`` x 100; idle cores = 2 - 1 - others (the worker's time is not a reason to dismiss it)."""
    monkeypatch.delenv(WORKERS_VARIABLE, raising=False)
    own, worker, others = 100.0, 60.0, others_busy * 100.0
    monkeypatch.setattr(_pool, "_IMPORTED", (0.0, 0.0, 0.0))
    monkeypatch.setattr(_pool, "_OWN_AT_IMPORT", 5.0)
    monkeypatch.setattr(_pool, "cpu_times", lambda: (1.0, 200.0 - own - worker - others, 200.0))
    monkeypatch.setattr(_pool, "process_jiffies", lambda pid: {1: own + 5.0, 2: worker}[pid])
    monkeypatch.setattr(_pool.os, "getpid", lambda: 1)
    monkeypatch.setattr(_pool.os, "cpu_count", lambda: 2)
    monkeypatch.setattr(_pool.os, "sched_getaffinity", lambda pid: {0, 1})
    assert _pool.worker_count((2,)) == expected


def test_process_jiffies_reads_this_process():
    """proc(5)'s utime + stime, in clock ticks: what os.times() says of this process, to a tick."""
    import os

    before = os.times()
    jiffies = _pool.process_jiffies(os.getpid())
    after = os.times()
    ticks = os.sysconf("SC_CLK_TCK")
    assert (before.user + before.system) * ticks - 2 <= jiffies <= (after.user + after.system) * ticks + 2
    assert jiffies > 0
    assert _pool.process_jiffies(-1) == 0.0  # no such process


def _worker_finished(pool, job):
    """As if the worker compiling ``job`` answered ok."""
    with pool._condition:
        pool._running.discard(job)
        pool._finished[job] = True
        pool._condition.notify_all()


def test_while_waiting_for_a_workers_job_the_process_compiles_the_earliest_others(monkeypatch):
    """The build needs a job a worker compiles (DAQP's solve, for its probe): meanwhile the process
    compiles the jobs no worker started, oldest first, instead of idling; then it waits."""
    from wbc.runtime import kernels

    pool = CompilePool(0)
    pool.submit(["kernel has_nan", "kernel has_non_finite", "op DAQP_SOLVE", "kernel qp_defect"])
    assert pool.take("op DAQP_SOLVE")
    pool._running.add("op DAQP_SOLVE")  # as if a worker had started it
    compiled = []

    def compile_job(job):
        compiled.append(job)
        if len(compiled) == 2:  # the worker finishes meanwhile
            _worker_finished(pool, "op DAQP_SOLVE")

    monkeypatch.setattr(kernels, "_workers", pool)
    monkeypatch.setattr(kernels, "_compile_job", compile_job)
    kernels._claim("op DAQP_SOLVE")
    assert compiled == ["kernel has_nan", "kernel has_non_finite"]  # oldest first, and no more once it was done
    assert pool.take("kernel qp_defect")  # left for whoever needs it
    pool.close()


def test_a_forked_child_leaves_its_parents_workers_alone():
    """A child forked after the pool started shares the workers' pipes: its close() (at its exit)
    must not stop them."""
    import os

    pool = CompilePool(1)
    try:
        child = os.fork()
        if child == 0:  # pragma: no cover - the child
            pool.close()
            os._exit(0)
        os.waitpid(child, 0)
        assert pool._processes[0].poll() is None  # still running
    finally:
        pool.close()
    assert pool._processes[0].poll() is not None


_EARLY = """
    import json, sys
    import wbc
    from wbc.runtime import kernels
    early = kernels._workers is not None
    numba_imported = "numba" in sys.modules
    robot = wbc.load_robot("youbot")
    controller = wbc.Controller(robot, tasks=[wbc.PostureTask(cost=1.0)])
    print(json.dumps(dict(early=early, numba=numba_imported, kept=kernels._workers is not None,
                          finished=[] if kernels._workers is None else sorted(kernels._workers._finished))))
"""


@pytest.mark.parametrize("workers", ["1", "0"])
def test_import_starts_a_worker_on_the_common_kernels_after_an_install(tmp_path, workers):
    """On an empty cache ``import wbc`` starts a worker (without importing numba itself) that
    compiles kernels every controller uses before any controller asks; none with WBC_COMPILE_WORKERS=0."""
    from wbc.runtime.kernels import COMMON_JOBS

    result = subprocess.run([sys.executable, "-c", textwrap.dedent(_EARLY)], capture_output=True, text=True,
                            cwd=NEUTRAL, timeout=600,
                            env={**child_environment(), "NUMBA_CACHE_DIR": str(tmp_path), WORKERS_VARIABLE: workers})
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["numba"] is False
    assert report["early"] is (workers == "1") and report["kept"] is (workers == "1")
    if workers == "1":
        assert set(report["finished"]) & set(COMMON_JOBS)  # the worker compiled common jobs


_JOBS_USED = """
    import json, sys
    import wbc
    from wbc.runtime import kernels
    used = set()
    lookup, fetch = kernels.__getattr__, kernels.callback  # every compiled function and op callback passes here
    kernels.__getattr__ = lambda name: used.add(f"kernel {name}") or lookup(name)
    kernels.callback = lambda op: used.add(f"op {op.spec.name}") or fetch(op)
    robot = wbc.load_robot(sys.argv[1])
    tasks = [wbc.PostureTask(cost=1.0)]
    if sys.argv[2] == "frame":
        tasks.insert(0, wbc.FrameTask("ee"))
    constraints = [wbc.NonholonomicBase()] if robot.base.is_nonholonomic else []
    wbc.Controller(robot, tasks=tasks, constraints=constraints)
    print(json.dumps(sorted(used)))
"""


@pytest.mark.parametrize(("robot", "tasks"), [("youbot", "frame"), ("puma560", "posture"), ("deluca_mm", "posture")])
def test_every_common_job_is_one_a_plain_controller_uses(robot, tasks):
    """kernels.COMMON_JOBS is written by hand: each of its jobs must be one that a DAQP controller
    uses whatever its tasks and robot (a worker compiling one nobody needs only costs a first
    start CPU) -- the jobs a build in a fresh process asks for, recorded where every compiled
    function (the module's ``__getattr__``) and op callback (``callback``) is fetched."""
    from wbc.runtime.kernels import COMMON_JOBS

    result = subprocess.run([sys.executable, "-c", textwrap.dedent(_JOBS_USED), robot, tasks], capture_output=True,
                            text=True, cwd=NEUTRAL, timeout=600, env=child_environment())
    assert result.returncode == 0, result.stderr
    used = set(json.loads(result.stdout.strip().splitlines()[-1]))
    assert {"kernel run_program", "op DAQP_SOLVE"} <= used  # (the recording sees the build's jobs)
    assert set(COMMON_JOBS) <= used, f"{robot}: not used: {sorted(set(COMMON_JOBS) - used)}"


def test_first_start_finds_numbas_own_cache_directory(tmp_path, monkeypatch):
    """Without numba, the first-start check looks where numba's own locator caches the interpreter
    (the oracle: :func:`_cache.cache_dir`, numba's locator): cold while that holds no index, warm after."""
    from wbc.runtime.kernels import _cache

    folder = Path(_cache.__file__).parent
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    from numba.core import config

    monkeypatch.setattr(config, "CACHE_DIR", str(tmp_path))
    directory = _cache.cache_dir(folder / "tick.py")
    assert directory is not None and tmp_path in directory.parents
    assert _cache.first_start(folder, "tick")
    tag = f"py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}"
    directory.mkdir(parents=True, exist_ok=True)
    (directory / f"tick.run_program-130.{tag}.nbi").write_bytes(b"")
    assert not _cache.first_start(folder, "tick")


def test_a_job_that_fails_while_waiting_does_not_fail_the_build(monkeypatch):
    """A job compiled only to fill the wait (not the build's own) may fail: the wait goes on."""
    from wbc.runtime import kernels

    pool = CompilePool(0)
    pool.submit(["op NO_SUCH_OP", "kernel has_nan", "op DAQP_SOLVE"])
    assert pool.take("op DAQP_SOLVE")
    pool._running.add("op DAQP_SOLVE")
    compiled = []

    def compile_job(job):
        compiled.append(job)
        if job == "op NO_SUCH_OP":
            raise KeyError(job)
        _worker_finished(pool, "op DAQP_SOLVE")

    monkeypatch.setattr(kernels, "_workers", pool)
    monkeypatch.setattr(kernels, "_compile_job", compile_job)
    kernels._claim("op DAQP_SOLVE")
    assert compiled == ["op NO_SUCH_OP", "kernel has_nan"]
    pool.close()


def test_a_forked_child_of_import_wbc_does_not_import_numba():
    result = subprocess.run([sys.executable, "-c", textwrap.dedent("""
        import os, sys
        import wbc
        child = os.fork()
        if child == 0:
            os._exit(3 if "numba" in sys.modules else 0)
        print(os.waitpid(child, 0)[1] >> 8)
    """)], capture_output=True, text=True, cwd=NEUTRAL, timeout=300, env=child_environment())
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "0"


def _twice(x):
    return 2.0 * x


def test_a_kernel_compiled_while_its_own_compile_waited_is_not_compiled_again(monkeypatch):
    """While the process waits for a worker before compiling a kernel, it compiles other jobs; one
    of them may compile that very kernel (as a callee): the waiting compile must then stop, not
    ask numba again (it refuses: the kernel is frozen to its signature once compiled)."""
    from wbc.runtime.kernels import _lazy

    kernel = _lazy.declared("float64(float64)")(_twice)

    def wait_and_compile_it_meanwhile(dispatcher):
        monkeypatch.setattr(_lazy, "before_compile", _lazy._nothing_before)
        _lazy.compile_declared(dispatcher)  # a job compiled while waiting, with this kernel as its callee

    monkeypatch.setattr(_lazy, "before_compile", wait_and_compile_it_meanwhile)
    _lazy.compile_declared(kernel)
    assert kernel(1.5) == 3.0
    assert len(kernel.overloads) == 1
