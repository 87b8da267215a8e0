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

import numpy as np
import pytest

from conftest import NEUTRAL, child_environment
from wbc.runtime.kernels._pool import WORKERS_VARIABLE, CompilePool

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
