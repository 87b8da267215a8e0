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
