"""Solver sweeps on Dask workers (benchmarks/sweep.py) and perturbed starts (benchmarks/starts.py).

Correctness only: no timing assertions. Dask (`distributed`) is part of the [test] extra, so these run
everywhere the suite runs.
"""

import math
import os
import shutil
import socket
import subprocess
import sys

import distributed  # [test] has it: a missing install must fail, not skip
import numpy as np
import pandas
import pytest

from benchmarks import dataset as ds
from benchmarks import solvers as sb
from benchmarks import starts as st
from benchmarks import sweep
from benchmarks.common import scenario_files
from conftest import ROOT, TASKS

SCENARIOS = ["deluca_parking", "youbot_reach"]  # equality rows; active limits
#: 2 scenarios x 2 starts x 3 ticks, 2 solvers, 2 settings
SWEEP = ["--ticks", "3", "--scenarios", *SCENARIOS, "--solvers", "daqp", "quadprog", "--settings", "default",
         "high_accuracy", "--starts", "2", "--no-progress"]
#: the columns of results.csv (qpbenchmark's) and solves.csv (wbc's) that do not depend on timing
RESULTS_COLUMNS = ["problem", "solver", "settings", "found", "primal_residual", "dual_residual", "duality_gap"]
SOLVES_COLUMNS = ["pass", "problem", "scenario", "start", "tick", "active", "solver", "settings", "warm", "found",
                  "success", "time_limit", "primal_residual", "dual_residual", "duality_gap", "ref_error"]


@pytest.fixture(scope="module")
def sweep_dataset(tmp_path_factory):
    """The two scenarios, 0.3 s each."""
    out = tmp_path_factory.mktemp("dataset")
    ds.record_all(out, TASKS, duration=0.3, show_progress=False, only=SCENARIOS)
    return out


@pytest.fixture(scope="module")
def serial_run(sweep_dataset, tmp_path_factory):
    """The sweep serially, with Dask made unimportable: the serial path must not need it."""
    out = tmp_path_factory.mktemp("serial")
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(sys.modules, "distributed", None)
        assert sb.main(["--dataset", str(sweep_dataset), "--out", str(out), *SWEEP]) == 0
    return out


@pytest.fixture(scope="module")
def cluster():
    """An existing cluster to pass by address: a LocalCluster of 2 processes, and a client of the test's own."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address="127.0.0.1:0") as local, \
            distributed.Client(local, set_as_default=False) as client:
        yield local.scheduler_address, client


def assert_same_non_timing_results(first, second):
    for name, columns in (("results.csv", RESULTS_COLUMNS), ("solves.csv", SOLVES_COLUMNS)):
        a, b = pandas.read_csv(first / name), pandas.read_csv(second / name)
        assert list(a.columns) == list(b.columns)
        pandas.testing.assert_frame_equal(a[columns], b[columns], check_exact=True)


def test_serial_run_sweeps_both_starts(serial_run):
    results = pandas.read_csv(serial_run / "results.csv")
    solves = pandas.read_csv(serial_run / "solves.csv")
    assert len(results) == 2 * 2 * 3 * 2 * 2  # scenarios x starts x ticks x solvers x settings
    # back to back: daqp cold and warm, quadprog cold (its wrapper ignores initvals), per settings
    assert len(solves) == len(results) + 2 * 2 * 3 * 2 * 3
    names = set(results["problem"])
    for sc in SCENARIOS:  # 3 ticks of each start, the perturbed one named so
        assert len({name for name in names if name.startswith(f"{sc}_0")}) == 3
        assert len({name for name in names if name.startswith(f"{sc}_s1_0")}) == 3
    assert len(names) == 12
    assert set(solves["start"]) == {0, 1}
    assert solves[solves["problem"].str.contains("_s1_")]["start"].eq(1).all()
    assert solves["found"].all()  # both active-set solvers solve every QP


def test_local_workers_give_the_serial_results(sweep_dataset, serial_run, tmp_path):
    out = tmp_path / "workers"
    assert sb.main(["--dataset", str(sweep_dataset), "--out", str(out), "--workers", "2", *SWEEP]) == 0
    assert_same_non_timing_results(serial_run, out)
    workers = min(2, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count())
    assert (f"run on a local Dask cluster (LocalCluster) of {workers} workers, {workers} threads"  # (capped: 1 core)
            in (out / "report.md").read_text())


def test_existing_cluster_by_address_gives_the_serial_results(sweep_dataset, serial_run, cluster, tmp_path):
    address, _ = cluster
    out = tmp_path / "cluster"
    assert sb.main(["--dataset", str(sweep_dataset), "--out", str(out), "--scheduler", address, *SWEEP]) == 0
    assert_same_non_timing_results(serial_run, out)
    assert f"run on the Dask cluster at {address} of 2 workers, 2 threads" in (out / "report.md").read_text()


def test_a_worker_with_another_version_is_refused(sweep_dataset, cluster, tmp_path, capsys):
    """A worker whose environment holds another qpbenchmark (a distribution found first on its sys.path)."""
    address, client = cluster
    fake = tmp_path / "fake-site"
    (fake / "qpbenchmark-0.0.1.dist-info").mkdir(parents=True)
    (fake / "qpbenchmark-0.0.1.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: qpbenchmark\n"
                                                                     "Version: 0.0.1\n")
    client.run(exec, f"import sys; sys.path.insert(0, {str(fake)!r})", {})
    try:
        with pytest.raises(SystemExit) as exit_info:
            sb.main(["--dataset", str(sweep_dataset), "--out", str(tmp_path / "out"), "--scheduler", address, *SWEEP])
    finally:
        client.run(exec, f"import sys; sys.path.remove({str(fake)!r})", {})
    assert exit_info.value.code == 1
    from importlib.metadata import version

    err = capsys.readouterr().err
    assert f"has qpbenchmark 0.0.1, this process {version('qpbenchmark')}" in err
    assert f"pip install qpbenchmark=={version('qpbenchmark')}" in err
    assert not (tmp_path / "out" / "results.csv").exists()


def test_unreachable_scheduler_is_a_clear_error(sweep_dataset, tmp_path, capsys):
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with pytest.raises(SystemExit) as exit_info:
        sb.main(["--dataset", str(sweep_dataset), "--out", str(tmp_path), "--scheduler", f"tcp://127.0.0.1:{port}",
                 "--connect-timeout", "1", *SWEEP])
    assert exit_info.value.code == 1
    err = capsys.readouterr().err
    assert f"no Dask scheduler reachable at 'tcp://127.0.0.1:{port}' within 1 s" in err
    assert "--workers N" in err and "Traceback" not in err


def test_missing_engine_names_the_extra(sweep_dataset, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(SystemExit) as exit_info:
        sb.main(["--dataset", str(sweep_dataset), "--out", str(tmp_path), "--workers", "2", *SWEEP])
    assert exit_info.value.code == 1
    assert 'needs Dask\'s distributed scheduler, which does not import here' in capsys.readouterr().err
    with pytest.raises(sweep.SweepError, match=r'pip install "wbc\[distributed\]"'):
        with sweep.executor(workers=1):
            pass


def test_benchmarks_import_no_engine():
    code = "import sys, benchmarks.solvers, benchmarks.sweep, wbc.app.cli; print('distributed' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "False"


def test_failed_work_unit_is_named(cluster):
    address, _ = cluster
    with sweep.executor(scheduler=address, timeout=5, show_progress=False) as run:
        assert run(math.sqrt, [9.0, 4.0], ["first", "second"]) == [3.0, 2.0]  # in the items' order
        with pytest.raises(sweep.SweepError, match=r"work unit 'bad unit' failed on its worker: ValueError: math "):
            run(math.sqrt, [4.0, -1.0], ["good unit", "bad unit"])


def test_lost_worker_is_named():
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                     dashboard_address="127.0.0.1:0") as local, \
            sweep.executor(scheduler=local.scheduler_address, timeout=5, show_progress=False) as run:
        with pytest.raises(sweep.SweepError, match="work unit 'dying unit': the worker running it died"):
            run(os._exit, [3], ["dying unit"])


def test_version_check_names_a_missing_package():
    here = {"wbc": "0.2.0", "qpbenchmark": "2.7.1"}
    sweep.check_versions(here, {"tcp://a:1": dict(here), "tcp://b:1": dict(here)})
    with pytest.raises(sweep.SweepError, match=r"worker tcp://b:1 has qpbenchmark -, this process 2\.7\.1"):
        sweep.check_versions(here, {"tcp://a:1": dict(here), "tcp://b:1": {"wbc": "0.2.0", "qpbenchmark": "-"}})


# ------------------------------------------------------------------ perturbed starts
@pytest.mark.parametrize("path", scenario_files(TASKS), ids=lambda path: path.stem)
def test_perturbed_starts_are_inside_the_limits_and_seeded(path):
    from wbc.app.scenario import load_scenario

    scenario = load_scenario(path)
    robot, q0 = scenario.robot, scenario.q0
    starts = [st.perturbed_configuration(robot, q0, scenario.name, start, 0) for start in (1, 2)]
    for q in starts:
        assert robot.within_limits(q)
        assert 0 < np.max(np.abs(q - q0)) <= 2 * st.AMPLITUDE  # a few cm / degrees off
    assert not np.array_equal(starts[0], starts[1])
    np.testing.assert_array_equal(st.perturbed_configuration(robot, q0, scenario.name, 1, 0), starts[0])
    assert not np.array_equal(st.perturbed_configuration(robot, q0, scenario.name, 1, 1), starts[0])
    with pytest.raises(ValueError, match="numbered from 1"):
        st.perturbed_configuration(robot, q0, scenario.name, 0, 0)


def test_recorded_starts_begin_at_the_perturbed_start_and_follow_the_seed(sweep_dataset, serial_run, tmp_path):
    from wbc.app.scenario import load_scenario

    copy = tmp_path / "dataset"
    shutil.copytree(sweep_dataset, copy)
    folder = ds.version_folder(copy)
    index, nominal = ds.load(copy)
    for sc in nominal:
        scenario = load_scenario(TASKS / f"{sc.name}.toml")
        expected = st.perturbed_configuration(scenario.robot, scenario.q0, sc.name, 1, 0)
        recorded = st.load_starts(folder, [sc], 2)[1]
        assert (recorded.name, recorded.start, recorded.label) == (sc.name, 1, f"{sc.name}_s1")
        np.testing.assert_array_equal(recorded.q[0], expected)
        assert recorded.ticks == sc.ticks and not np.array_equal(recorded.H, sc.H)
    here = sweep.Here(show_progress=False)
    assert st.ensure_starts(folder, index, nominal, 2, 0, here) == 0  # recorded by the serial run, still fresh
    assert st.ensure_starts(folder, index, nominal, 2, 1, here) == 2  # another seed: recorded again
    with pytest.raises(FileNotFoundError, match="perturbed start 2 of deluca_parking is not recorded"):
        st.load_starts(folder, nominal, 3)


@pytest.mark.parametrize("options, expected", [
    (["--connect-timeout", "nan", "--workers", "1"], "--connect-timeout nan: give a finite number of seconds > 0"),
    (["--connect-timeout", "-5", "--workers", "1"], "--connect-timeout -5.0: give a finite number of seconds > 0"),
    (["--scheduler", "notaurl"], "--scheduler 'notaurl' is not a scheduler address"),
    (["--workers", "0"], "--workers 0: give 1 or more"),
])
def test_sweep_options_are_checked_before_anything_starts(options, expected, tmp_path):
    """nan was a raw KeyError traceback, -5 a garbled message, a malformed address an error followed by a 20 s
    hang and an 'Exception ignored ... TimeoutError' traceback (issue 22 §6): now exit 2, one line."""
    code = "import sys; from wbc.app.cli import main; sys.exit(main(sys.argv[1:]))"
    result = subprocess.run([sys.executable, "-c", code, "bench", "--checkout", str(ROOT), "solvers",
                             "--out", str(tmp_path), *options], capture_output=True, text=True, timeout=300)
    assert result.returncode == 2, result.stderr
    assert expected in result.stderr and "Traceback" not in result.stderr and "Exception ignored" not in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_workers_are_capped_at_the_cores_available(capsys):
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert sweep.checked_options(1000, None, 10.0) == cores
    assert f"--workers 1000: capped at {cores}" in capsys.readouterr().err
    assert sweep.checked_options(1, None, 10.0) == 1 and capsys.readouterr().err == ""


def test_ctrl_c_in_wbc_bench_exits_130_without_a_traceback(tmp_path):
    import signal

    process = subprocess.Popen([sys.executable, "-m", "wbc", "bench", "--checkout", str(ROOT), "solvers",
                                "--regenerate", "--dataset", str(tmp_path / "data"), "--out", str(tmp_path / "out"),
                                "--no-progress", "--ticks", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    try:
        assert "recording the dataset" in process.stderr.readline()  # it runs: now interrupt it
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=300)
    finally:
        process.kill()
    assert process.returncode == 130 and err.strip() == "wbc: interrupted", err


def test_no_progress_draws_no_bar_while_the_missing_dataset_is_recorded(tmp_path):
    result = subprocess.run([sys.executable, "-m", "wbc", "bench", "--checkout", str(ROOT), "solvers",
                             "--dataset", str(tmp_path / "data"), "--out", str(tmp_path / "out"), "--no-progress",
                             "--ticks", "2", "--scenarios", "youbot_reach", "--solvers", "daqp", "--settings",
                             "default", "--qpbenchmark-only"], capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr
    assert "it/s" not in result.stderr and "%|" not in result.stderr, result.stderr
