"""The command line: ``wbc run`` prints a summary and writes a plot; errors exit with status 2."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import wbc
from conftest import NEUTRAL, ROOT, TASKS, require, tomllib
from wbc.app.cli import main


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
    (summary,) = json.loads(capsys.readouterr().out)
    assert summary["scenario"] == "youbot_reach" and summary["solver"] == "daqp"
    assert summary["ticks"] == 50
    assert summary["worst_position_limit_violation"] == 0.0


@pytest.mark.parametrize("solver", wbc.available_solvers())
def test_json_alone_on_stdout_with_every_backend(solver):
    """`--json` leaves stdout to the JSON whatever the backend prints on first use (highspy 1.16's
    banner), in a process of its own as a user runs it."""
    result = wbc_process("run", str(TASKS / "youbot_circle.toml"), "--duration", "0.1", "--solver", solver, "--json",
                         "--no-progress", timeout=600)
    assert result.returncode == 0, result.stderr
    (summary,) = json.loads(result.stdout)
    assert summary["solver"] == solver and summary["ticks"] == 10


def test_json_has_one_shape_for_one_file_and_several(capsys):
    """Always a list of objects, one per file in the order given, the same keys for the same
    scenario (with --plot too: tests/test_manipulability_scenario.py)."""
    reach, parking = str(TASKS / "youbot_reach.toml"), str(TASKS / "deluca_parking.toml")
    options = ["--duration", "0.2", "--no-progress", "--json"]
    assert main(["run", reach, *options]) == 0
    alone = json.loads(capsys.readouterr().out)
    assert main(["run", parking, reach, *options]) == 0
    both = json.loads(capsys.readouterr().out)
    assert isinstance(alone, list) and isinstance(both, list)
    assert [s["scenario"] for s in alone] == ["youbot_reach"]
    assert [s["scenario"] for s in both] == ["deluca_parking", "youbot_reach"]
    assert set(alone[0]) == set(both[1])
    # a PositionTask has no orientation to report
    assert "orientation_error_max_rad" in both[1] and "orientation_error_max_rad" not in both[0]


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


def test_text_summary_of_a_position_only_task(capsys):
    assert main(["run", str(TASKS / "deluca_parking.toml"), "--duration", "0.2", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "orientation err            not tracked" in out and "mrad" not in out


def test_the_summary_says_how_the_loop_was_closed(capsys):
    require("mujoco")
    assert main(["run", CIRCLE, "--duration", "0.1", "--no-progress"]) == 0
    assert capsys.readouterr().out.startswith("scenario youbot_circle  (solver daqp, kinematic loop)\n")
    options = ["--duration", "0.1", "--no-progress", "--sim", "mujoco", "--noise", "1e-4", "--delay", "1"]
    assert main(["run", CIRCLE, *options]) == 0
    header = "scenario youbot_circle  (solver daqp, MuJoCo loop: velocity servos, noise 0.0001, delay 1 tick)\n"
    assert capsys.readouterr().out.startswith(header)
    assert main(["run", CIRCLE, *options, "--json"]) == 0
    (summary,) = json.loads(capsys.readouterr().out)
    assert summary["loop"] == "mujoco" and summary["loop_details"] == "velocity servos, noise 0.0001, delay 1 tick"


def test_version(capsys):
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out == f"wbc {version('wbc')}\n"


def test_solvers_command(capsys):
    assert main(["solvers"]) == 0
    assert "daqp" in capsys.readouterr().out


# ---------------------------------------------------------------- errors before the run

CIRCLE = str(TASKS / "youbot_circle.toml")


#: what the ``wbc`` executable runs (pyproject's [project.scripts]; ``python -m wbc`` too)
CONSOLE = "from wbc.app.cli import console; console()"


def wbc_process(*args: str, code: str = CONSOLE, cwd=NEUTRAL, timeout: float = 300,
                **kwargs) -> subprocess.CompletedProcess:
    """``wbc ARGS`` as a separate process (its stdout/stderr/exit status as a user sees them);
    ``code``: the ``python -c`` source that runs it (the executable's, unless a test adds to it)."""
    return subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, **kwargs)


def test_bad_scenario_file_exits_2_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((TASKS / "youbot_circle.toml").read_text().replace("duration = 20.0", "durration = 20.0"))
    result = wbc_process("run", str(bad))
    assert result.returncode == 2
    assert result.stderr.startswith(f"wbc: error: {bad}:") and "did you mean 'duration'?" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf"])
def test_duration_must_be_positive_and_finite(capsys, value):
    assert main(["run", CIRCLE, "--no-progress", f"--duration={value}"]) == 2
    assert capsys.readouterr().err.startswith("wbc: error: --duration must be a finite number of seconds > 0")


@pytest.mark.parametrize("options, message", [
    (["--noise", "1e-4"], "add --sim mujoco"),
    (["--delay", "1"], "add --sim mujoco"),
    (["--sim", "mujoco", "--noise=-1e-4"], "--noise is a standard deviation"),
    (["--sim", "mujoco", "--noise", "nan"], "--noise is a standard deviation"),
])
def test_noise_and_delay_options_are_checked(capsys, options, message):
    assert main(["run", CIRCLE, "--duration", "0.1", "--no-progress", *options]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("module, options, extra", [
    ("matplotlib", ["--plot", "out.png"], 'pip install "wbc[plot]"'),
    ("mujoco", ["--sim", "mujoco"], 'pip install "wbc[sim]"'),
])
def test_missing_extra_fails_before_the_run(monkeypatch, tmp_path, capsys, module, options, extra):
    import wbc.app.closed_loop

    def no_run(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(wbc.app.closed_loop, "run", no_run)
    monkeypatch.setitem(sys.modules, module, None)  # import matplotlib / mujoco -> ImportError
    monkeypatch.chdir(tmp_path)
    assert main(["run", CIRCLE, "--no-progress", *options]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wbc: error:") and extra in err


def test_plot_into_a_missing_folder_creates_it(tmp_path, capsys):
    plot = tmp_path / "new" / "deeper" / "circle.png"
    assert main(["run", CIRCLE, "--duration", "0.1", "--no-progress", "--plot", str(plot)]) == 0
    assert plot.stat().st_size > 10_000


def test_plot_folder_that_cannot_be_made_fails_before_the_run(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    assert main(["run", CIRCLE, "--no-progress", "--plot", str(tmp_path / "file" / "x.png")]) == 2
    assert "cannot create the folder" in capsys.readouterr().err


# ---------------------------------------------------------------- output files
#: ``python -c`` code running ``wbc ARGS`` in which a run that starts exits with status 99
NO_RUN = ("import sys, wbc.app.closed_loop as loop\n"
          "def started(*args, **kwargs):\n    print('the run started', file=sys.stderr); sys.exit(99)\n"
          "loop.run = started\n"
          "from wbc.app.cli import main; sys.exit(main(sys.argv[1:]))")


def files_under(folder: Path) -> list[str]:
    return sorted(str(path.relative_to(folder)) for path in folder.rglob("*"))


@pytest.mark.parametrize("option, value, message", [
    ("--plot", "out.xyz", "--plot: out.xyz has suffix '.xyz'; give a name ending in .png (or .pdf, .svg, .svgz, "
                          ".eps, ...)"),
    ("--plot", "out", "--plot: out has no suffix; give a name ending in .png"),
    ("--plot", "", "--plot: needs a file name"),
    ("--plot", "some_dir", "--plot: some_dir is a folder; give a file name in it, e.g. some_dir/run.png"),
    ("--plot", "some_dir/", "--plot: some_dir/ is a folder"),
    ("--plot", "/proc/out.png", "--plot: cannot write in /proc: "),
    ("--plot", "a_file/new/out.png", "--plot: cannot create the folder a_file/new: a_file is not a folder"),
    ("--plot", "new/deeper/out.svgx", "--plot: new/deeper/out.svgx has suffix '.svgx'"),
    ("--html", "some_dir", "--html: some_dir is a folder; give a file name in it, e.g. some_dir/run.html"),
    ("--html", "/proc/x.html", "--html: cannot write in /proc: "),
    ("--html", "replay.png", "--html: replay.png has suffix '.png'; give a name ending in .html (or .htm)"),
    ("--html", "", "--html: needs a file name"),
])
def test_an_output_that_cannot_be_written_is_refused_before_the_run(tmp_path, option, value, message):
    if value.startswith("/proc") and not Path("/proc/self").exists():
        pytest.skip("needs Linux's /proc (a folder no one can create files in)")
    (tmp_path / "some_dir").mkdir()
    (tmp_path / "a_file").write_text("")
    before = files_under(tmp_path)
    result = wbc_process("run", CIRCLE, "--no-progress", option, value, code=NO_RUN, cwd=tmp_path)
    assert result.returncode == 2, result.stderr
    assert result.stderr.startswith(f"wbc: error: {message}") and result.stderr.count("\n") == 1, result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""
    assert files_under(tmp_path) == before, "nothing written, no folder made"


def test_plot_format_follows_the_suffix(tmp_path):
    plot = tmp_path / "circle.PDF"
    assert main(["run", CIRCLE, "--duration", "0.1", "--no-progress", "--plot", str(plot)]) == 0
    assert plot.read_bytes().startswith(b"%PDF")
    assert files_under(tmp_path) == ["circle.PDF"], "no temporary file left"


#: ``python -c`` code running ``wbc ARGS`` in which the file ``--plot`` / ``--html`` writes is
#: interrupted by a real SIGINT (Ctrl-C) once part of it is written
INTERRUPTED_WRITE = (
    "import os, signal, sys\n"
    "import matplotlib.figure, wbc.app.outputs\n"
    "def savefig(self, stream, **kwargs):\n"
    "    stream.write(b'half a plot'); stream.flush(); os.kill(os.getpid(), signal.SIGINT)\n"
    "matplotlib.figure.Figure.savefig = savefig\n"
    "replace = wbc.app.outputs.os.replace\n"
    "def interrupted_replace(source, target):\n"
    "    if str(target).endswith('.html'): os.kill(os.getpid(), signal.SIGINT)\n"
    "    replace(source, target)\n"
    "wbc.app.outputs.os.replace = interrupted_replace\n"
    "from wbc.app.cli import main; sys.exit(main(sys.argv[1:]))")


@pytest.mark.parametrize("option, name", [("--plot", "out.png"), ("--html", "out.html")])
def test_ctrl_c_while_an_output_is_written_leaves_no_file(tmp_path, option, name):
    if option == "--html":
        require("viser")
    target = tmp_path / "new" / name
    result = wbc_process("run", CIRCLE, "--duration", "0.1", "--no-progress", "--json", option, str(target),
                         code=INTERRUPTED_WRITE)
    assert result.returncode == 130, result.stderr
    assert result.stderr == "wbc: interrupted\n"
    assert json.loads(result.stdout)[0]["ticks"] == 10, "the summaries came before the files"
    assert files_under(tmp_path) == ["new"], "no partial file, no temporary file"


def test_an_existing_output_is_replaced_whole_or_kept(tmp_path):
    from wbc.app.outputs import write_atomically

    target = tmp_path / "plot.png"
    target.write_bytes(b"the previous plot")

    def failing(stream):
        stream.write(b"half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space left"):
        write_atomically(target, failing)
    assert target.read_bytes() == b"the previous plot" and files_under(tmp_path) == ["plot.png"]
    write_atomically(target, lambda stream: stream.write(b"the new plot"))
    assert target.read_bytes() == b"the new plot" and files_under(tmp_path) == ["plot.png"]
    umask = os.umask(0)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask, "the permissions of a file opened for writing"


def test_a_failed_write_after_the_run_is_one_line(tmp_path, capsys, monkeypatch):
    import wbc.app.outputs

    def full_disk(*args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(wbc.app.outputs.os, "replace", full_disk)
    assert main(["run", CIRCLE, "--duration", "0.1", "--no-progress", "--plot", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err == "wbc: error: --plot: the plot was not written: [Errno 28] No space left on device\n"
    assert files_under(tmp_path) == []


@pytest.mark.parametrize("args", [["run", CIRCLE, "--duration", "0.2", "--no-progress", "--json"], ["solvers"]])
def test_broken_pipe_exits_quietly(args):
    process = subprocess.Popen([sys.executable, "-c", CONSOLE, *args], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True, cwd=NEUTRAL)
    process.stdout.close()  # the reader is gone before wbc writes (like `| head -0`)
    stderr = process.stderr.read()
    assert process.wait(timeout=300) in (0, 1)
    assert "Traceback" not in stderr and "Exception ignored" not in stderr, stderr


# ---------------------------------------------------------------- the executable's exit
def test_the_executable_is_console_and_python_m_wbc_runs_it():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts == {"wbc": "wbc.app.cli:console"}
    result = subprocess.run([sys.executable, "-m", "wbc", "run", CIRCLE, "--duration", "0.2", "--no-progress",
                             "--json"], cwd=NEUTRAL, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)[0]["ticks"] == 20  # all of it, through a pipe (block-buffered stdout)


def test_the_executable_runs_the_exit_handlers_then_flushes_and_keeps_the_status(tmp_path):
    code = ("import atexit, sys\n"
            "atexit.register(lambda: sys.stdout.write('handler ran\\n'))\n" + CONSOLE)
    done = wbc_process("solvers", code=code)
    assert done.returncode == 0 and "daqp" in done.stdout and done.stdout.endswith("handler ran\n"), done
    failed = wbc_process("run", str(tmp_path / "missing.toml"), code=code)
    assert failed.returncode == 2 and failed.stdout == "handler ran\n" and "wbc: error:" in failed.stderr


def test_the_executable_waits_for_threads_that_are_not_daemons(tmp_path):
    marker = tmp_path / "thread.txt"
    code = ("import threading, time\n"
            f"threading.Thread(target=lambda: (time.sleep(0.5), open({str(marker)!r}, 'w').write('done'))).start()\n"
            + CONSOLE)
    result = wbc_process("solvers", code=code)
    assert result.returncode == 0 and marker.read_text() == "done"


def test_the_executable_stops_its_compile_workers(tmp_path):
    """A first start (empty cache, one compile worker forced): the worker is gone when wbc has exited."""
    code = ("import atexit, os, sys\n"
            "def report():\n"
            "    from wbc.runtime import kernels\n"
            "    print('workers', *(kernels._workers.pids if kernels._workers else ()))\n"
            "atexit.register(report)\n" + CONSOLE)
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "WBC_COMPILE_WORKERS": "1"}
    result = wbc_process("run", CIRCLE, "--duration", "0.1", "--no-progress", code=code, timeout=600,
                         env=environment)
    assert result.returncode == 0, result.stderr
    pids = [int(word) for word in result.stdout.splitlines()[-1].split()[1:]]
    assert len(pids) == 1
    with pytest.raises(ProcessLookupError):  # (killed and reaped by the pool's exit handler)
        os.kill(pids[0], 0)


# ---------------------------------------------------------------- wbc bench
PLANTED = textwrap.dedent("""
    from pathlib import Path
    Path({marker!r}).write_text("planted code ran")
    def main(options):
        return 0
""")


def plant_benchmarks(folder, marker):
    """A ``benchmarks`` package (and tasks/, pyproject naming wbc) whose import writes ``marker``."""
    (folder / "benchmarks").mkdir(parents=True)
    (folder / "tasks").mkdir()
    (folder / "pyproject.toml").write_text('[project]\nname = "wbc"\n')
    for name in ("__init__.py", "solvers.py"):
        (folder / "benchmarks" / name).write_text(PLANTED.format(marker=str(marker)))


def test_bench_never_imports_benchmarks_from_the_working_directory(tmp_path, monkeypatch):
    from wbc.app.cli import find_benchmarks

    marker = tmp_path / "marker"
    plant_benchmarks(tmp_path / "parent", marker)
    cwd = tmp_path / "parent" / "child"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    editable = Path(wbc.__file__).resolve().parents[1] == ROOT  # else: installed, the checkout is not found
    assert find_benchmarks() == (ROOT if editable else None)
    result = wbc_process("bench", "solvers", "--help", cwd=cwd)
    if editable:
        assert result.returncode == 0 and "usage" in result.stdout
    else:
        assert result.returncode == 2 and "--checkout PATH" in result.stderr
    assert not marker.exists()


def test_bench_checkout_option(tmp_path):
    marker = tmp_path / "marker"
    plant_benchmarks(tmp_path / "checkout", marker)
    assert wbc_process("bench", "--checkout", str(tmp_path / "checkout"), "solvers").returncode == 0
    assert marker.read_text() == "planted code ran"
    result = wbc_process("bench", "--checkout", str(tmp_path), "solvers")
    assert result.returncode == 2
    assert "is not a wbc source checkout" in result.stderr and "Traceback" not in result.stderr
