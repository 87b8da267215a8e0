"""``wbc singularities MODEL``: prints the certified conditions and the agreement counts, exit 0."""

import re

import pytest

from wbc.app.cli import main


@pytest.mark.parametrize("model, expected", [
    ("youbot", ["whole_body", "arm", "sin(theta2 + theta3 + theta4) = 0", "Kapustina eq. 4"]),
    ("scorbot_er4pc", ["sin(theta3) = sin(q3 - q2) = 0", "cos(q4) = 0"]),
    ("puma560", ["sin(theta5) = 0", "a3 sin(theta3) + d4 cos(theta3) = 0",
                 "a2 cos(theta2) + a3 cos(theta2 + theta3) - d4 sin(theta2 + theta3) = 0"]),
])
def test_singularities_prints_conditions_and_all_agree(capsys, model, expected):
    assert main(["singularities", model, "--samples", "300", "--on-set", "20", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    for text in expected:
        assert text in out
    counts = re.findall(r"(\d+) / (\d+)\s+agree", out)
    assert counts and all(a == b for a, b in counts)
    assert {int(b) for _, b in counts} == {300, 20}
    assert out.rstrip().endswith("all agree")


def test_singularities_unknown_model_exits_2(capsys):
    assert main(["singularities", "r2d2"]) == 2
    assert "r2d2" in capsys.readouterr().err


def test_singularities_exits_1_on_disagreement(capsys, monkeypatch):
    import numpy as np

    from wbc.analysis import singularity

    def broken(robot, rng, samples, on_set, subsystem):
        report = singularity.Agreement("random configurations")
        report.add(False, np.zeros(robot.nq))
        return [report]

    monkeypatch.setattr(singularity, "verify", broken)
    assert main(["singularities", "puma560"]) == 1
    assert "DISAGREEMENT" in capsys.readouterr().out


@pytest.mark.parametrize("options, option", [
    (["--seed", "-1"], "--seed"), (["--samples", "-5"], "--samples"), (["--on-set", "-5"], "--on-set"),
    (["--samples", "0"], "--samples"), (["--samples", "x"], "--samples"),
])
def test_counts_and_seeds_out_of_range_are_usage_errors(capsys, options, option):
    """--seed -1 was a numpy traceback; --samples -5 --on-set -5 checked nothing and printed 'all agree',
    exit 0 (issue 22 §6)."""
    with pytest.raises(SystemExit) as exit_info:
        main(["singularities", "youbot", *options])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {option}: invalid integer >= " in err and "Traceback" not in err


def test_a_check_that_ran_no_case_fails(capsys, monkeypatch):
    """An empty agreement (0 / 0) confirms nothing: the command reports a disagreement, exit 1."""
    from wbc.analysis import singularity

    monkeypatch.setattr(singularity, "verify", lambda *args, **kwargs: [singularity.Agreement("no case")])
    assert main(["singularities", "puma560"]) == 1
    assert "0 / 0" in capsys.readouterr().out
