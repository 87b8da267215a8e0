"""The benchmark harnesses in benchmarks/ work (correctness only: no timing assertions here)."""

import inspect
import json
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import qpsolvers

from benchmarks import dataset as ds
from benchmarks import solvers as sb
from benchmarks import wbc_qpbenchmark as qb
from benchmarks.common import scenario_files, shifted_geometric_mean
from conftest import ROOT, TASKS


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


# ------------------------------------------------------------ qpbenchmark test set
def test_conversion_to_qpbenchmark_keeps_wbc_qp(small_dataset):
    """lb/ub, G x <= h, A x = b describe the same feasible set and optimum as wbc's [I; C] layout."""
    from wbc.qp.problem import QP
    from wbc.solvers import make_solver

    out, _, _ = small_dataset
    _, scenarios = ds.load(out)
    assert {sc.name for sc in scenarios} == {path.stem for path in scenario_files(TASKS)}  # every one recorded
    rng = np.random.default_rng(7)

    def same_violations(C, upper, lower, n_ineq, n_eq, x_center):
        problem = ds.make_problem(np.eye(C.shape[1]), np.zeros(C.shape[1]), C, upper, lower, n_ineq, n_eq)
        for scale in (0.0, 1e-6, 1e-3, 1e-1, 1.0):  # x_ref (feasible), then ever larger violations
            x = x_center + scale * rng.standard_normal(C.shape[1])
            values = np.concatenate([x, C @ x])
            wbc_violation = max(0.0, np.max(lower - values), np.max(values - upper))
            converted = qpsolvers.Solution(problem, found=True, x=x).primal_residual()
            assert converted == pytest.approx(wbc_violation, rel=1e-12, abs=1e-15), scale

    solver = make_solver("daqp", {"primal_tol": 1e-12, "dual_tol": 1e-12})
    for sc in scenarios:
        active = np.flatnonzero(qb.WbcQpbenchmark.tick_has_active_constraint(sc))
        for k in {0, sc.ticks - 1, *active[:1]}:
            problem = sc.problem(k)
            same_violations(sc.C[k], sc.upper[k], sc.lower[k], sc.n_ineq, sc.n_eq, sc.x_ref[k])
            if sc.n_eq:  # the recorded equalities have b = 0 (no-slip rows): also a b != 0
                upper, lower = sc.upper[k].copy(), sc.lower[k].copy()
                upper[-sc.n_eq:] = lower[-sc.n_eq:] = 0.3
                same_violations(sc.C[k], upper, lower, sc.n_ineq, sc.n_eq, sc.x_ref[k])
            qp = QP(sc.n, sc.n_ineq, sc.n_eq)  # wbc's own form, solved by wbc's own DAQP backend
            for name in ("H", "c", "C", "upper", "lower"):
                getattr(qp, name)[...] = getattr(sc, name)[k]
            own = solver.solve(qp)
            other = qpsolvers.solve_problem(problem, solver="quadprog")  # the converted form, another algorithm
            assert own.success and other.found
            np.testing.assert_allclose(other.x, own.x, atol=1e-9)
            np.testing.assert_allclose(other.x, sc.x_ref[k], atol=1e-9)


def test_conversion_rejects_what_it_would_drop_and_splits_rows_with_two_sides(small_dataset):
    out, _, _ = small_dataset
    _, scenarios = ds.load(out)
    sc = next(s for s in scenarios if s.n_ineq and s.n_eq)  # deluca_parking: both kinds of rows
    arrays = [sc.H[0], sc.c[0], sc.C[0], sc.upper[0].copy(), sc.lower[0].copy(), sc.n_ineq, sc.n_eq]
    n, p = sc.n, sc.n_ineq
    two_sided = list(arrays)
    two_sided[4] = arrays[4].copy()
    two_sided[4][n + 1] = -1.0  # a lower side on inequality row 1 (a band row of strict priorities under DAQP)
    split = ds.make_problem(*two_sided)
    np.testing.assert_array_equal(split.G, np.vstack([sc.C[0][:p], -sc.C[0][1:2]]))  # -G_1 x <= 1, after G
    np.testing.assert_array_equal(split.h, np.r_[sc.upper[0][n:n + p], 1.0])
    loose = list(arrays)
    loose[3] = arrays[3].copy()
    loose[3][-1] += 1.0  # an equality row whose upper and lower bounds differ
    with pytest.raises(ValueError, match="equality row"):
        ds.make_problem(*loose)
    problem = ds.make_problem(*arrays)
    np.testing.assert_array_equal(problem.h, sc.upper[0][n:n + p])
    np.testing.assert_array_equal(problem.b, sc.upper[0][n + p:])
    np.testing.assert_array_equal(problem.lb, sc.lower[0][:n])


def test_select_ticks_takes_both_kinds_evenly():
    active = np.zeros(100, dtype=bool)
    active[40:50] = True
    ticks = qb.select_ticks(active, 8)
    assert len(ticks) == 8 and len(set(ticks)) == 8
    assert active[ticks].sum() == 4 and ticks[active[ticks]].tolist() == [40, 43, 46, 49]
    assert qb.select_ticks(active, 30)[active[qb.select_ticks(active, 30)]].size == 10  # all 10, 20 without
    assert active[qb.select_ticks(active, 95)].sum() == 10 and len(qb.select_ticks(active, 95)) == 95
    np.testing.assert_array_equal(qb.select_ticks(active, 0), np.arange(100))
    np.testing.assert_array_equal(qb.select_ticks(~active, 4), [0, 40, 49, 99])  # 90 active, 10 not: 2 + 2


def test_test_set_holds_the_recorded_qps(small_dataset, monkeypatch):
    from qpbenchmark.benchmark import load_test_set

    out, _, index = small_dataset
    test_set = qb.WbcQpbenchmark(out, ticks=4)
    recorded = {e["scenario"] for e in index["scenarios"] if e["status"] == "ok"}
    problems = list(test_set)
    assert {p.scenario for p in problems} == recorded and len(problems) == 4 * len(recorded)
    assert len({p.name for p in problems}) == len(problems)
    assert set(test_set.tolerances) == set(test_set.solver_settings) == set(qb.SETTINGS)
    assert {t.runtime for t in test_set.tolerances.values()} == {0.01}  # the control period
    assert test_set.tolerances["mid_accuracy"].primal == 1e-6
    assert set(sb.WARM_START) >= {"daqp", "proxqp", "osqp", "quadprog", "clarabel", "piqp", "highs"}
    assert {"daqp", "proxqp", "osqp", "quadprog", "clarabel", "piqp", "highs"} <= test_set.solvers  # [test] has all
    by_name = {sc.name: sc for sc in test_set.scenarios}
    for problem in problems:
        sc, k = by_name[problem.scenario], problem.tick
        assert problem.name == f"{sc.name}_{k:05d}"
        np.testing.assert_array_equal(problem.P, sc.H[k])
        assert problem.active == bool(sc.active[k, :sc.n + sc.n_ineq].any())
        np.testing.assert_array_equal(problem.x_ref, sc.x_ref[k])
    assert any(p.active for p in problems) and not all(p.active for p in problems)
    parts = list(test_set.parts(5))
    assert [p.name for part in parts for p in part] == [p.name for p in problems]
    assert test_set.count_problems() == len(problems)  # the parts did not change the set
    # qpbenchmark's CLI imports the file as a module of its own and builds the set without arguments
    monkeypatch.setenv("WBC_QPBENCHMARK_DATASET", str(out))
    monkeypatch.setattr(sys, "path", list(sys.path))  # load_test_set appends benchmarks/ to it
    try:
        loaded = load_test_set(str(ROOT / "benchmarks" / "wbc_qpbenchmark.py"))
    finally:
        sys.modules.pop("wbc_qpbenchmark", None)
    assert type(loaded).__name__ == "WbcQpbenchmark" and type(loaded) is not qb.WbcQpbenchmark
    assert loaded.count_problems() == sum(min(qb.TICKS, e["ticks"]) for e in index["scenarios"] if e["status"] == "ok")
    with pytest.raises(ValueError, match="no_such"):
        qb.WbcQpbenchmark(out, scenarios=["no_such"])


@pytest.fixture(scope="module")
def solver_run(small_dataset, tmp_path_factory):
    """`wbc bench solvers` on 2 ticks per scenario: qpbenchmark's run, its report, wbc's report."""
    out, _, _ = small_dataset
    report = tmp_path_factory.mktemp("solvers")
    assert sb.main(["--dataset", str(out), "--ticks", "2", "--out", str(report), "--no-progress"]) == 0
    return out, report


def test_qpbenchmark_runs_the_test_set(solver_run):
    import pandas
    import qpbenchmark

    out, report = solver_run
    test_set = qb.WbcQpbenchmark(out, ticks=2)
    results = qpbenchmark.Results(str(report / "results.csv"), test_set)
    keys = set(zip(results.df["problem"], results.df["solver"], results.df["settings"], strict=True))
    assert len(keys) == len(results.df) == test_set.count_problems() * len(test_set.solvers) * len(qb.SETTINGS)
    solves = pandas.read_csv(report / "solves.csv").to_dict("records")
    cold = [r for r in solves if r["pass"] == "qpbenchmark"]
    assert len(cold) == len(results.df)
    for r in cold:  # active-set solvers at 1e-9: exact, at the reference
        if r["solver"] in ("daqp", "quadprog") and r["settings"] == "high_accuracy":
            assert r["success"] and r["ref_error"] < 1e-8, r
    # wbc's aggregation reproduces qpbenchmark's own (success rate, runtime shm ratios)
    tolerances = test_set.tolerances
    success = results.build_success_rate_df({s: t.primal for s, t in tolerances.items()},
                                            {s: t.dual for s, t in tolerances.items()},
                                            {s: t.gap for s, t in tolerances.items()})
    runtime = results.build_shgeom_df("runtime", shift=sb.SHIFT_S,
                                      not_found_values={s: t.runtime for s, t in tolerances.items()})
    floors = "floors" in inspect.signature(results.build_shgeom_df).parameters  # qpbenchmark >= 2.7
    primal = results.build_shgeom_df("primal_residual", shift=sb.SHIFT_S, not_found_values={
        s: t.primal for s, t in tolerances.items()}, **({"floors": {s: t.primal for s, t in tolerances.items()}}
                                                         if floors else {}))
    for settings in tolerances:
        stats = sb.config_stats(cold, settings, tolerances)
        best = min(s["shm_s"] for s in stats.values())
        best_primal = min(s["primal_shm"] for s in stats.values())
        for (solver, _), s in stats.items():
            assert s["success"] == pytest.approx(success.loc[solver, settings])
            assert s["shm_s"] / best == pytest.approx(runtime.loc[solver, settings], rel=1e-9)
            if floors:
                assert s["primal_shm"] / best_primal == pytest.approx(primal.loc[solver, settings], rel=1e-6)
    second = [r for r in solves if r["pass"] == "back to back"]
    assert len([r for r in second if not r["warm"]]) == len(cold)  # every solver and settings, cold
    assert {r["solver"] for r in second if r["warm"]} == {s for s in test_set.solvers if sb.WARM_START.get(s)}
    text = (report / "wbc_qpbenchmark.md").read_text()
    assert test_set.title in text and "### Mid accuracy" in text
    own = (report / "report.md").read_text()
    assert "### settings: mid_accuracy" in own and "### back to back, settings: mid_accuracy" in own


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
    from wbc.app.scenario import load_scenario

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
    from wbc.app.cli import build_parser, find_benchmarks

    editable = Path(wbc.__file__).resolve().parents[1] == ROOT  # else: installed, the checkout is not found
    assert find_benchmarks() == (ROOT if editable else None)
    assert find_benchmarks(ROOT) == ROOT
    args = build_parser().parse_args(["bench", "solvers", "--ticks", "3"])
    assert args.suite == "solvers" and args.options == ["--ticks", "3"]


def _placo_run(ticks: int = 40):
    """The youbot_circle peer spec, the configurations and targets of its first ticks."""
    from benchmarks import peers
    from benchmarks.peer_setups import spec_from_scenario
    from wbc.app.scenario import load_scenario

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


def test_placo_runs_summary_ratios_per_run_and_of_the_fastest_runs():
    """Per alternation, wbc's median over placo's; and the fastest run of each side over the
    other's (a host that slows whole runs: here wbc's second and placo's third), on made-up runs."""
    from benchmarks import peers

    def run(median_us: float) -> np.ndarray:
        return np.full(11, median_us * 1e-6)

    runs = {peers.WBC: [run(3.0), run(5.0), run(3.1)], peers.PLACO_QP: [run(3.2), run(3.3), run(3.4)],
            peers.PLACO: [run(4.8), run(5.0), run(7.5)]}
    summary = peers._runs_summary(runs)
    np.testing.assert_allclose(summary["median_ratio_vs_placo"][peers.WBC], [3.0 / 4.8, 5.0 / 5.0, 3.1 / 7.5])
    assert summary["fastest_ratio_vs_placo"][peers.WBC] == pytest.approx(3.0 / 4.8)
    assert summary["fastest_ratio_vs_placo"][peers.PLACO_QP] == pytest.approx(3.2 / 4.8)
    (line,) = [line for line in peers._runs_table(summary, None) if line.startswith(f"- {peers.WBC} / placo")]
    assert line.endswith("the fastest run of each 0.62") and "median tick 0.62 (0.41–1.00)" in line


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
    assert run["steady_s"] < run["first_tick_s"]  # a first tick runs the checked pipeline, not the native tick


def test_the_users_loop_is_the_same_work_in_wbc_and_placo():
    """wbc on placo's QP and placo, each in its own loop from the same start with the circle target
    computed in the loop, follow the same configurations (runs where placo does)."""
    from benchmarks import peers
    from benchmarks.peer_setups import WbcSetup, placo_gains

    placo = peers.find_placo(os.environ.get("WBC_PLACO_PYTHON"))
    if not placo.runs:
        pytest.skip(placo.status)
    _, spec, configurations, targets = _placo_run(5)
    result = peers.run_placo(placo, spec, configurations, targets, warmup=2, closed_loop=False, user_loop=300)
    times, wbc_q = peers.wbc_user_loop(WbcSetup(placo_gains(spec), peers.PLACO_QP), configurations[0], 300)
    placo_q = np.asarray(result["user_loop_q"])
    assert placo_q.shape == wbc_q.shape == (300, 8) and len(result["user_loop_times"]) == 300 and np.all(times > 0)
    assert np.abs(wbc_q[-1] - configurations[0]).max() > 0.05  # the circle moved the robot
    assert np.abs(placo_q - wbc_q).max() < 1e-9


def test_the_split_of_the_users_loop_times_the_peers_loop_and_nests_its_times(monkeypatch):
    """benchmarks.user_loop runs wbc's loop of the peer comparison (same configurations), and the
    program's own times nest: the solve inside the native call inside the timed ``step``."""
    from benchmarks import peers, user_loop
    from benchmarks.peer_setups import WbcSetup, spec_from_scenario
    from wbc.app.scenario import load_scenario

    run = user_loop.split_loop(ticks=40, warmup=5)  # ticks 5..44: last read after 10, 20, 30, 40
    assert [len(run[part]) for part in user_loop.PARTS] == [36, 36, 36, 4, 4]  # not the 4 ticks after a read
    monkeypatch.setattr(user_loop, "SAMPLE_EVERY", 1)  # last read after every tick: the times of the same ticks
    run = user_loop.split_loop(ticks=40, warmup=5)
    assert all(len(run[part]) == 40 for part in user_loop.PARTS)
    step, native, solve = (np.asarray(run[part]) for part in ("step", "native call", "solve"))
    assert np.all(solve > 0.0) and np.all(solve < native) and np.all(native < step)
    assert 0.0 < run["clock_pair_ns"] < 1e4
    scenario = load_scenario(TASKS / "youbot_circle.toml")
    _, configurations = peers.wbc_user_loop(WbcSetup(spec_from_scenario(scenario)), scenario.q0, 45)
    assert np.abs(configurations[-1] - scenario.q0).max() > 1e-3  # the circle moved the robot
    np.testing.assert_allclose(run["q"], configurations[-1], rtol=0.0, atol=1e-12)


def test_endurance_times_a_fixed_workload_and_the_same_tick_beside_the_ticks(capsys):
    from benchmarks import endurance

    endurance.endurance(TASKS / "youbot_circle.toml", ticks=2000, windows=2)
    out = capsys.readouterr().out
    assert "non-optimal ticks: 0" in out and "the fixed workload (the machine's tail): p50" in out
    assert "the same tick replayed (the machine's tail for this work): p50" in out
    windows = [line.split() for line in out.splitlines() if line.split()[:1] in (["1"], ["2"])]
    assert len(windows) == 2 and all(len(words) == 10 for words in windows)  # tick, RSS, workload, same tick
    assert endurance.fixed_workload(7).args == (range(7),)


def test_the_replayed_tick_is_the_same_tick_every_time():
    """The endurance control: tick 20 of the circle loop again and again -- the same command bit for
    bit (the same path), and a tick that moves the robot (not a resting one)."""
    from benchmarks import endurance
    from wbc.app.scenario import load_scenario

    replay = endurance.same_tick(TASKS / "youbot_circle.toml", ticks=20)
    commands = [replay().copy() for _ in range(5)]
    assert all(np.array_equal(command, commands[0]) for command in commands)
    assert np.abs(commands[0]).max() > 1e-3
    scenario = load_scenario(TASKS / "youbot_circle.toml")
    controller, q = scenario.make_controller(), scenario.q0.copy()
    for k in range(20):  # the same loop written out: its tick 20 is the replayed one
        scenario.reference_task.set_target(*scenario.reference(k * scenario.dt))
        q = scenario.robot.integrate(q, controller.step(q), scenario.dt)
    scenario.reference_task.set_target(*scenario.reference(20 * scenario.dt))
    np.testing.assert_allclose(controller.step(q), commands[0], rtol=0.0, atol=1e-12)
