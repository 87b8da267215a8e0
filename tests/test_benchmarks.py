"""The benchmark harnesses in benchmarks/ work (correctness only: no timing assertions here)."""

import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, TASKS

if str(ROOT) not in sys.path:  # benchmarks/ is a top-level package of the checkout, not installed
    sys.path.insert(0, str(ROOT))

from benchmarks import dataset as ds  # noqa: E402
from benchmarks import solvers as sb  # noqa: E402
from benchmarks.common import scenario_files, shifted_geometric_mean  # noqa: E402


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    """Every scenario of tasks/, 0.3 s each, plus a broken scenario file."""
    tasks = tmp_path_factory.mktemp("tasks")
    for path in scenario_files(TASKS):
        shutil.copy(path, tasks / path.name)
    (tasks / "zz_broken.toml").write_text('[robot]\nname = "no_such_robot"\n')
    out = tmp_path_factory.mktemp("dataset")
    folder, index = ds.record_all(out, tasks, duration=0.3, show_progress=False)
    return out, folder, index


def test_dataset_records_every_scenario_and_reports_failures(small_dataset):
    out, folder, index = small_dataset
    names = {entry["scenario"] for entry in index["scenarios"]}
    assert names == {path.stem for path in scenario_files(TASKS)} | {"zz_broken"}
    broken = next(e for e in index["scenarios"] if e["scenario"] == "zz_broken")
    assert broken["status"].startswith("error")
    assert json.loads((folder / "index.json").read_text())["version"] == ds.VERSION
    rows = (folder / "index.csv").read_text().splitlines()
    assert rows[0].startswith("scenario,tick,time,robot,n,n_ineq,n_eq")
    assert len(rows) == 1 + sum(e.get("ticks", 0) for e in index["scenarios"])


def test_dataset_round_trip_and_reference(small_dataset):
    out, _, index = small_dataset
    _, scenarios = ds.load(out)
    assert len(scenarios) == sum(e["status"] == "ok" for e in index["scenarios"])
    import qpsolvers

    for sc in scenarios:
        assert sc.ticks == 30
        assert np.max(sc.ref_residuals) < ds.REF_TOL
        np.testing.assert_allclose(sc.x_controller, sc.x_ref, atol=1e-7)
        solution = qpsolvers.solve_problem(sc.problem(sc.ticks - 1), solver="quadprog")
        np.testing.assert_allclose(solution.x, sc.x_ref[-1], atol=1e-7)


def test_dataset_command_exits_nonzero_on_a_failing_scenario(tmp_path):
    tasks = tmp_path / "tasks"
    tasks.mkdir()
    shutil.copy(TASKS / "youbot_circle.toml", tasks)
    (tasks / "broken.toml").write_text("not toml at all [")
    assert ds.main(["--out", str(tmp_path / "out"), "--tasks", str(tasks), "--duration", "0.05",
                    "--no-progress"]) == 1


def test_shifted_geometric_mean():
    assert shifted_geometric_mean([5.0, 5.0], 10) == pytest.approx(5.0)
    assert shifted_geometric_mean([0.0, 30.0], 10) == pytest.approx(np.sqrt(10 * 40) - 10)
    with pytest.raises(ValueError):
        shifted_geometric_mean([-1.0])


def test_solver_benchmark_rows_and_report(small_dataset, tmp_path):
    out, _, index = small_dataset
    _, scenarios = ds.load(out)
    configs = sb.make_configs(["daqp", "quadprog"], ["default", "high"])
    assert sb.Config("quadprog", "high", True) not in configs  # qpsolvers ignores initvals for quadprog
    assert sb.Config("daqp", "high", True) in configs
    rows = sb.benchmark(scenarios, configs, ticks=2, repeats=1, time_limit=None, show_progress=False)
    assert len(rows) == 2 * len(scenarios) * len(configs)
    assert all(r["found"] for r in rows)
    high = [r for r in rows if r["settings"] == "high"]
    assert all(r["ref_error"] < 1e-6 for r in high)
    failed = dict(rows[0], success=False, runtime=1.0)
    assert sb.summarize([failed])["sgm_us"] == pytest.approx(rows[0]["time_limit"] * 1e6)
    assert "daqp (warm)" in sb.settings_table(rows, "high")


def test_accuracy_settings_cover_the_required_solvers():
    for name in sb.SOLVERS:
        options = sb.accuracy_settings(name, 1e-9)
        assert name == "quadprog" or options, name


def test_synthetic_chains_match_between_urdf_and_mjcf(tmp_path):
    import mujoco  # part of the [test] extra: a missing install must fail, not skip

    import wbc
    from benchmarks.scaling import chain_mjcf, chain_urdf, initial_configuration

    for dof in (8, 21):
        (tmp_path / "c.urdf").write_text(chain_urdf(dof))
        robot = wbc.load_robot(tmp_path / "c.urdf")
        assert robot.nv == dof and robot.base.is_mobile
        model = mujoco.MjModel.from_xml_string(chain_mjcf(dof))
        data = mujoco.MjData(model)
        rng = np.random.default_rng(dof)
        for q in [initial_configuration(dof)] + [rng.uniform(-1, 1, dof) for _ in range(3)]:
            data.qpos[:] = q
            mujoco.mj_kinematics(model, data)
            np.testing.assert_allclose(data.site("ee").xpos, robot.frame_pose(q, "ee")[:3, 3], atol=1e-12)


def test_peer_setups_solve_the_same_qp():
    """Pink solves wbc's QP once wbc uses the peers' log6 error; the hand-rolled tick equals wbc's."""
    from benchmarks import peers  # Pink and mink are part of the [test] extra
    from benchmarks.peer_setups import spec_from_scenario
    from wbc.scenario import load_scenario

    scenario = load_scenario(TASKS / "youbot_circle.toml")
    spec = spec_from_scenario(scenario)
    setups = peers.make_setups(scenario, spec)
    result = peers.shared_q_pass(scenario, setups, 60)
    v = result["commands"]
    assert np.abs(v[peers.HAND] - v[peers.WBC]).max() < 1e-9
    assert np.abs(v["Pink"] - v[peers.LOG6]).max() < 1e-9
    # mink differs by its SE3.jlog small-angle branch only (documented in benchmarks/README.md)
    assert np.abs(v["mink"] - v[peers.LOG6]).max() < 1e-5
    diagnosis = peers.diagnose(scenario, spec, result, True)
    assert diagnosis["mink"]["max_tight_tol_exact_jlog"] < 1e-9


def test_cli_bench_finds_the_checkout():
    import wbc
    from wbc.cli import build_parser, find_benchmarks

    editable = Path(wbc.__file__).resolve().parents[1] == ROOT  # else: installed, the checkout is not found
    assert find_benchmarks() == (ROOT if editable else None)
    assert find_benchmarks(ROOT) == ROOT
    args = build_parser().parse_args(["bench", "solvers", "--ticks", "3"])
    assert args.suite == "solvers" and args.options == ["--ticks", "3"]


def _placo_run(ticks: int = 40):
    """The youbot_circle peer spec, the configurations and targets of its first ticks."""
    from benchmarks import peers
    from benchmarks.peer_setups import spec_from_scenario
    from wbc.scenario import load_scenario

    scenario = load_scenario(TASKS / "youbot_circle.toml")
    spec = spec_from_scenario(scenario)
    configurations = peers.shared_q_pass(scenario, [peers.WbcSetup(spec, peers.WBC)], ticks)["q"]
    return scenario, spec, configurations, peers.reference_poses(scenario)[:ticks]


def test_placo_peer_reads_its_input(tmp_path, capsys):
    """The placo side parses what the harness writes, and rejects malformed input (placo not needed)."""
    from benchmarks import peers, placo_peer

    _, spec, configurations, targets = _placo_run(5)
    document = peers.placo_input(spec, configurations, targets, warmup=3, closed_loop=True)
    stack, run = placo_peer.read_input(json.dumps(document))
    assert stack["joint_names"] == spec.joint_names and stack["regularization"] == spec.damping
    assert set(stack["posture_target"]) == set(spec.joint_names[3:])  # the base is free, as in wbc's PostureTask
    np.testing.assert_array_equal(run["configurations"], configurations)
    np.testing.assert_array_equal(run["targets"], targets)
    assert run["warmup"] == 3 and run["closed_loop"] is True
    for broken, message in [("{", "not JSON"), ("[]", "'stack' and 'run'"),
                            ({**document, "stack": {k: v for k, v in document["stack"].items() if k != "dt"}},
                             "lacks dt"),
                            ({**document, "stack": {**document["stack"], "velocity_limits": {"wheel": 1.0}}},
                             "not in joint_names"),
                            ({**document, "run": {**document["run"], "targets": targets[:4].tolist()}},
                             r"run.targets must be \(5, 4, 4\)"),
                            ({**document, "run": {**document["run"], "configurations": [[0.0, 1.0]] * 5}},
                             r"run.configurations must be \(ticks, 8\)")]:
        with pytest.raises(ValueError, match=message):
            placo_peer.read_input(broken if isinstance(broken, str) else json.dumps(broken))
    (tmp_path / "bad.json").write_text("{}")
    assert placo_peer.main([str(tmp_path / "bad.json")]) == 2
    assert "placo_peer: input needs" in capsys.readouterr().err


def test_peers_reports_placo_not_run(tmp_path, monkeypatch):
    """Without placo the benchmark runs and says why placo did not."""
    from benchmarks import peers

    monkeypatch.setitem(sys.modules, "placo", None)  # `import placo` fails here, whatever is installed
    assert peers.find_placo(None).status.startswith("not run: `import placo` fails here")
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\necho \"ModuleNotFoundError: No module named 'placo'\" >&2\nexit 1\n")
    fake.chmod(0o755)
    placo = peers.find_placo(str(fake))
    assert not placo.runs and "No module named 'placo'" in placo.status
    assert not peers.find_placo(str(tmp_path / "missing")).runs
    out = tmp_path / "out"
    assert peers.main(["--scenarios", "youbot_circle", "--repeats", "1", "--warmup", "5", "--no-peers",
                       "--placo-python", str(fake), "--no-progress", "--out", str(out)]) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["placo"]["status"] == placo.status
    assert results["scenarios"]["youbot_circle"]["placo"] is None
    assert peers.PLACO_QP not in results["scenarios"]["youbot_circle"]["latency"]
    assert f"placo: {placo.status}" in (out / "report.md").read_text()


def test_placo_solves_wbc_on_placo_gains():
    """placo's commands equal wbc's on placo's QP (runs where placo does: here or $WBC_PLACO_PYTHON)."""
    from benchmarks import peers
    from benchmarks.peer_setups import WbcSetup, placo_gains

    placo = peers.find_placo(os.environ.get("WBC_PLACO_PYTHON"))
    if not placo.runs:
        pytest.skip(placo.status)
    scenario, spec, configurations, targets = _placo_run()
    result = peers.run_placo(placo, spec, configurations, targets, warmup=2, closed_loop=True)
    wbc_on_placo_qp = WbcSetup(placo_gains(spec), peers.PLACO_QP)
    reference = np.array([(wbc_on_placo_qp.set_target(pose), wbc_on_placo_qp.step(q))[1]
                          for q, pose in zip(configurations, targets, strict=True)])
    assert np.abs(np.asarray(result["commands"]) - reference).max() < 1e-9
    assert len(result["times"]) == len(configurations)
    # placo's own closed loop starts at the first configuration and follows its own commands
    loop = np.asarray(result["closed_loop_q"])
    np.testing.assert_allclose(loop[0], configurations[0])
    assert np.abs(loop[1] - scenario.robot.integrate(configurations[0], reference[0], spec.dt)).max() < 1e-9


def test_cold_costs_are_measured_in_a_fresh_process():
    from benchmarks import cold

    run = cold.measure(TASKS / "youbot_circle.toml")
    assert set(run) == {"import_s", "first_build_s", "first_tick_s", "steady_s", "build_s", "later_first_tick_s"}
    assert all(value > 0.0 for value in run.values())
    assert run["steady_s"] < run["first_tick_s"]  # a first tick pays for code run the first time
