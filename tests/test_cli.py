"""The command line: ``wbc run`` prints a summary and writes a plot; errors exit with status 2."""

import json

import pytest

from conftest import TASKS
from wbc.cli import main


def test_run_prints_summary_and_writes_plot(tmp_path, capsys):
    plot = tmp_path / "circle.png"
    assert main(["run", str(TASKS / "youbot_circle.toml"), "--duration", "1.0", "--no-progress",
                 "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    for text in ("ticks", "position error", "worst limit violation", "tick latency median / p99"):
        assert text in out
    assert plot.stat().st_size > 10_000


def test_run_json_summary(capsys):
    assert main(["run", str(TASKS / "youbot_reach.toml"), "--duration", "0.5", "--no-progress", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["ticks"] == 50
    assert summary["worst_position_limit_violation"] == 0.0


@pytest.mark.parametrize("solver", ["osqp", "proxqp"])
def test_run_with_another_solver(capsys, solver):
    assert main(["run", str(TASKS / "youbot_circle.toml"), "--duration", "0.2", "--no-progress",
                 "--solver", solver]) == 0
    assert f"solver {solver}" in capsys.readouterr().out


def test_errors_exit_with_status_2(tmp_path, capsys):
    assert main(["run", str(tmp_path / "missing.toml")]) == 2
    bad = tmp_path / "bad.toml"
    bad.write_text('[robot]\nname = "youbot"\n[[tasks]]\ntype = "NoSuchTask"\n')
    assert main(["run", str(bad)]) == 2
    assert "NoSuchTask" in capsys.readouterr().err
    assert main(["run", str(TASKS / "youbot_circle.toml"), "--solver", "nope"]) == 2


def test_solvers_command(capsys):
    assert main(["solvers"]) == 0
    assert "daqp" in capsys.readouterr().out
