"""Long runs keep bounded memory: rows every ``stride`` ticks (first tick's q and v, the peak of
every other series), the summary over every tick."""

import tracemalloc
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import TASKS
from wbc.app.closed_loop import run
from wbc.app.scenario import load_scenario
from wbc.core.errors import InvalidInputError

POSTURE_ONLY = ('[robot]\nname = "youbot"\ninitial_configuration = [0, 0, 0, 0, 0.5, 1.0, 1.2, 0]\n'
                '[controller]\nduration = 1.0\n'
                '[[tasks]]\ntype = "PostureTask"\ncost = 1.0\ngain = 0.1\n')


@pytest.fixture(scope="module")
def circle():
    return load_scenario(TASKS / "youbot_circle.toml")


def bucket_max(values: np.ndarray, stride: int) -> np.ndarray:
    """The largest value of each run of ``stride`` rows (the last may be shorter), written out."""
    return np.array([values[start:start + stride].max(axis=0) for start in range(0, len(values), stride)])


def test_a_decimated_run_keeps_the_first_tick_of_each_row_and_the_peaks(circle):
    full = run(circle, duration=0.5)  # 50 ticks, every one kept
    kept = run(circle, duration=0.5, max_rows=7)
    assert full.stride == 1 and full.ticks == 50 and full.q.shape == (51, 8)
    stride = 8  # ceil(50 / 7): 7 rows, the last of 2 ticks
    assert kept.stride == stride and kept.ticks == 50 and kept.time.shape == (7,)
    np.testing.assert_allclose(kept.time, np.arange(0, 50, stride) * circle.dt)
    # the loop is deterministic: the same commands, only fewer of them kept
    np.testing.assert_array_equal(kept.q[:-1], full.q[:-1:stride])
    np.testing.assert_array_equal(kept.q[-1], full.q[-1])
    np.testing.assert_array_equal(kept.v, full.v[::stride])
    np.testing.assert_array_equal(kept.tool_path[:-1], full.tool_path[:-1:stride])
    np.testing.assert_array_equal(kept.base_path[-1], full.base_path[-1])
    for name in ("position_error", "orientation_error", "velocity_violation", "velocity_ratio", "wheel_ratio"):
        np.testing.assert_array_equal(getattr(kept, name), bucket_max(getattr(full, name), stride), err_msg=name)
    np.testing.assert_array_equal(kept.position_violation[0], full.position_violation[0])
    np.testing.assert_array_equal(kept.position_violation[1:], bucket_max(full.position_violation[1:], stride))
    # the summary is over every tick (latencies are measured anew in each run: compared in the next test)
    exact, summary = full.summary(), kept.summary()
    for key in exact:
        if "latency" not in key and "solve_time" not in key:
            assert summary[key] == pytest.approx(exact[key], rel=1e-12, abs=0.0), key
    assert summary["position_error_rms_m"] == pytest.approx(np.sqrt(np.mean(full.position_error ** 2)), rel=1e-12)
    assert summary["position_error_max_m"] > full.position_error[::stride].max(), "the peak falls between rows"


class ScriptedController:
    """A stand-in controller: v = 0, with the latencies and successes of a script."""

    def __init__(self, tick_times: np.ndarray, solve_times: np.ndarray, failures: set[int], nv: int):
        self.script, self.failures, self.nv, self.count = (tick_times, solve_times), failures, nv, 0
        self.solver = SimpleNamespace(name="scripted")
        self.last = None

    def step(self, q: np.ndarray) -> np.ndarray:
        k = self.count
        self.last = SimpleNamespace(success=k not in self.failures, tick_time=self.script[0][k],
                                    solve_time=self.script[1][k], conflicts=[f"scripted {k}"])
        self.count += 1
        return np.zeros(self.nv)


def test_latency_percentiles_and_fallbacks_are_over_every_tick(tmp_path, rng):
    path = tmp_path / "posture.toml"
    path.write_text(POSTURE_ONLY)
    scenario = load_scenario(path)  # 100 ticks, no reference task
    tick_times = rng.lognormal(np.log(5e-6), 0.3, 100)
    tick_times[37] = 4e-3  # one spike, between two kept rows' first ticks
    solve_times = 0.3 * tick_times
    controller = ScriptedController(tick_times, solve_times, {3, 58, 99}, scenario.robot.nv)
    result = run(scenario, controller=controller, max_rows=9)  # stride 12: rows of 12 ticks, the last of 4
    assert result.stride == 12 and result.time.shape == (9,)
    summary = result.summary()
    assert summary["ticks"] == 100 and summary["fallback_ticks"] == 3 == result.fallback_ticks
    assert result.conflicts == [(4, ("scripted 3",)), (59, ("scripted 58",)), (100, ("scripted 99",))]
    assert summary["tick_latency_median_us"] == pytest.approx(np.median(tick_times) * 1e6, rel=1e-12)
    assert summary["tick_latency_p99_us"] == pytest.approx(np.percentile(tick_times, 99) * 1e6, rel=1e-12)
    assert summary["solve_time_median_us"] == pytest.approx(np.median(solve_times) * 1e6, rel=1e-12)
    np.testing.assert_array_equal(result.tick_time, bucket_max(tick_times, 12))
    assert result.tick_time[3] == 4e-3, "the spike is kept in its row"


def test_peak_memory_grows_by_the_latencies_alone(circle):
    """Twice the ticks at the same rows: the peak grows by the 16 bytes per tick of the exact
    latency percentiles, not by the rows (before: ~500 bytes per tick for the youBot)."""
    peaks = []
    for duration in (50.0, 150.0):  # 5 000 and 15 000 ticks into 500 rows
        tracemalloc.start()
        result = run(circle, duration=duration, max_rows=500)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert result.q.shape[0] <= 501
    growth = (peaks[1] - peaks[0]) / 10_000
    assert growth < 40, f"{growth:.0f} bytes per tick"


def test_a_run_needs_a_tick_and_a_row(circle):
    with pytest.raises(InvalidInputError, match="at least one tick"):
        run(circle, duration=1e-9)
    for rows in (0, -3, 2.5, True):
        with pytest.raises(InvalidInputError, match="max_rows must be an int"):
            run(circle, duration=0.1, max_rows=rows)


def test_the_manipulability_of_a_decimated_run_says_it_is_sampled():
    from wbc.app.cli import format_summary
    from wbc.app.closed_loop import manipulability_traces
    from wbc.model.manipulability import manipulability

    scenario = load_scenario(TASKS / "youbot_stretch.toml")
    full, kept = run(scenario, duration=0.5), run(scenario, duration=0.5, max_rows=10)  # 50 ticks, stride 5
    exact, sampled = manipulability_traces([(scenario, full)]).summary(0), manipulability_traces([(scenario, kept)])
    assert "manipulability_sampled_every_ticks" not in exact
    summary = sampled.summary(0)
    assert summary["manipulability_sampled_every_ticks"] == 5
    every_fifth = [manipulability(scenario.robot, q, "ee", "all") for q in [*full.q[:-1:5], full.q[-1]]]
    assert summary["manipulability_min"] == pytest.approx(min(every_fifth), rel=1e-12)
    assert summary["manipulability_min"] >= exact["manipulability_min"]
    text = format_summary("youbot_stretch", "daqp", kept.summary() | {"loop": "kinematic"} | summary)
    assert text.splitlines()[-1].endswith("(sampled: one tick in 5)")


def test_coarsening_a_record_is_recording_it_coarser(circle):
    full, kept = run(circle, duration=0.5), run(circle, duration=0.5, max_rows=7)
    coarse = full.coarsened(7)
    assert coarse.stride == kept.stride == 8 and coarse.statistics is full.statistics
    for name in ("time", "q", "v", "position_error", "orientation_error", "position_violation", "velocity_violation",
                 "velocity_ratio", "base_path", "tool_path", "wheel_ratio"):
        np.testing.assert_array_equal(getattr(coarse, name), getattr(kept, name), err_msg=name)
    np.testing.assert_array_equal(coarse.tick_time, bucket_max(full.tick_time, 8))
    assert full.coarsened(50) is full and kept.coarsened(3).stride == 24
    for rows in (0, -3, 2.5):  # (0 divided by zero)
        with pytest.raises(InvalidInputError, match="rows must be an int >= 1"):
            full.coarsened(rows)
