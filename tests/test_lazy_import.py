"""numba is imported only when compiled code is first needed; its on-disk cache is never stale.

``import wbc`` (and ``wbc.analysis.singularity``, ``wbc.trajectory``, ``wbc solvers``, ``wbc --help``)
must not import numba, nor qpsolvers and scipy (~0.2 s: imported when a qpsolvers backend is built or
listed, scipy's LAPACK when the Python path of manipulability first needs it); building a controller
loads the kernels, and a DAQP controller never imports qpsolvers. numba keys a cached function
on its own source file only, so :mod:`wbc.runtime.kernels._cache` deletes the package's entries when
any kernel source changes: checked here on a small package with a cross-file call, whose
stale cache numba alone would load.
"""

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from conftest import NEUTRAL, child_environment
from wbc.collision.warm_up import warm_up as warm_up_collision
from wbc.runtime import kernels
from wbc.runtime.kernels import _cache, tick


@pytest.fixture(scope="module")
def warm():
    """Every kernel compiled (or loaded) in this process, so that their cache is warm for the subprocesses."""
    kernels.warm_up()
    warm_up_collision()


def _python(code: str, env: dict | None = None, cwd: Path | str = NEUTRAL) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          env={**child_environment(), **(env or {})}, cwd=cwd, timeout=300)


def test_import_does_not_import_numba():
    result = _python("""
        import sys
        import wbc, wbc.analysis.singularity, wbc.trajectory
        from wbc.runtime import kernels
        assert kernels.FRAME_GAIN == 24 and kernels.FRAME_SETTINGS == 28  # the layouts need no numba
        print(sorted(name for name in sys.modules if name.split(".")[0] in ("numba", "llvmlite", "qpsolvers", "scipy")))
    """)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "[]"


@pytest.mark.parametrize("argv", [["solvers"], ["--help"]])
def test_cli_without_kernels_does_not_import_numba(argv):
    result = _python(f"""
        import sys
        from wbc.app.cli import main
        try:
            status = main({argv!r})
        except SystemExit as exc:
            status = exc.code
        print("numba" in sys.modules, status)
    """)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "False 0"


def test_building_a_controller_loads_the_kernels(warm):
    result = _python("""
        import sys
        import wbc
        robot = wbc.load_robot("youbot")
        assert "numba" not in sys.modules
        ee = wbc.FrameTask("ee", 1.0, 0.5)
        controller = wbc.Controller(robot, tasks=[ee, wbc.PostureTask(cost=1e-3)])
        ee.set_target([[1.0, 0, 0, 0.3], [0, 1, 0, 0], [0, 0, 1, 0.4], [0, 0, 0, 1]])
        controller.step(robot.neutral())
        print("numba" in sys.modules, "qpsolvers" in sys.modules)
        wbc.available_solvers()
        print("qpsolvers" in sys.modules)
    """)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["True", "False", "True"]
    assert result.stderr == ""  # warm cache: no compile message


def test_fetched_kernels_are_plain_attributes_of_their_declared_signature(warm):
    """Once fetched (compiled) no lookup goes through the module __getattr__ (the tick path),
    and a compiled function has its one declared signature (calls convert to it)."""
    namespace = vars(kernels)
    for module, names in kernels.COMPILED.items():
        topic = vars(getattr(kernels, module))
        kernels.prepare(*names)
        for name in names:
            assert namespace[name] is topic[name]
            assert len(topic[name].signatures) == 1, name
        # every public compiled function of a topic module is re-exported
        dispatchers = {name for name, value in topic.items() if not name.startswith("_")
                       and hasattr(value, "py_func") and value.__module__ == topic["__name__"]}
        assert dispatchers == set(names), module
    with pytest.raises(AttributeError):
        kernels.no_such_kernel  # noqa: B018


def test_the_interpreter_and_the_generated_callbacks_are_loaded_from_the_cache(warm):
    """run_program, and an op's callback generated from its declaration, are read from numba's
    cache by the next process (not compiled again), the callback from the file next to the
    package's cache."""
    result = _python("""
        from wbc.runtime import kernels
        kernels.load()
        stats = kernels.run_program.stats
        kernels.callback(kernels.HAS_NAN)
        compiled = kernels._callbacks["HAS_NAN"]
        print(sum(stats.cache_hits.values()), sum(stats.cache_misses.values()), compiled.cache_hits,
              compiled._pyfunc.__code__.co_filename)
    """)
    assert result.returncode == 0, result.stderr
    hits, misses, callback_hits, source = result.stdout.split()
    assert (hits, misses, callback_hits) == ("1", "0", "1")
    assert Path(source).parent == kernels.cache_directory and Path(source).name.startswith(tick.GENERATED_PREFIX)
    assert result.stderr == ""


def test_loading_compiles_nothing_and_a_program_prepares_the_interpreter(warm):
    """load() imports the kernel modules without compiling (reading) anything, the interpreter
    included; making a tick program prepares it (when a controller is built, never in a tick)."""
    result = _python("""
        from wbc.runtime import kernels
        from wbc.runtime.kernels import tick
        kernels.load()
        loaded = len(tick.run_program.signatures)
        from wbc.runtime.program import TickProgram
        TickProgram()
        print(loaded, len(tick.run_program.signatures), "run_program" in vars(kernels))
    """)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["0", "1", "True"]


def test_generated_sources_are_written_once_and_replace_the_stale_ones(tmp_path):
    first = _cache.write_generated(tmp_path, "gen_", "x = 1\n")
    stamp = first.stat().st_mtime_ns
    entry = _cache.cache_dir(first) / f"{first.stem}.run_program-10.py311.nbi"  # numba's entry of the first
    entry.write_bytes(b"")
    assert _cache.write_generated(tmp_path, "gen_", "x = 1\n") == first
    assert first.stat().st_mtime_ns == stamp  # not rewritten: numba's index of it stays valid
    second = _cache.write_generated(tmp_path, "gen_", "x = 2\n")
    assert second != first and second.read_text() == "x = 2\n"
    assert not first.exists() and not entry.exists()  # generated from other sources: gone with its entries
    assert _cache.write_generated(tmp_path / "missing", "gen_", "x = 3\n") is None  # not writable: in memory


def test_collision_warm_up_compiles_every_kernel_python_calls_and_both_ops(warm):
    """``wbc warmup`` covers the collision package: in a fresh process, its warm_up leaves each kernel
    that Python calls compiled for one signature, and both tick-program ops built."""
    result = _python("""
        from wbc.collision import avoidance, footprint, footprint_kernels, kernels
        from wbc.collision.warm_up import warm_up
        warm_up()
        names = ["world_poses", "pair_distances", "damper_rows", "corner_rows", "avoidance_rows", "insert_pair",
                 "distance_of", "bound_of"]
        counts = [len(getattr(kernels, name).signatures) for name in names]
        counts.append(len(footprint_kernels.footprint_rows.signatures))
        built = avoidance.avoidance_op.cache_info().currsize, footprint.footprint_op.cache_info().currsize
        print(counts, built)
    """)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split("\n")[0] == f"{[1] * 9} (1, 1)"


def test_warmup_command(warm):
    result = subprocess.run([sys.executable, "-m", "wbc.app.cli", "warmup"], capture_output=True, text=True,
                            timeout=300, cwd=NEUTRAL, env=child_environment())
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("numba kernels ready in ")
    assert result.stderr == ""


# ----------------------------------------------------------------- the cache rule


def test_source_stamp_follows_every_file_and_numba(tmp_path):
    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "b.py").write_text("y = 2\n")
    stamp = _cache.source_stamp(tmp_path, "0.60.0")
    assert _cache.source_stamp(tmp_path, "0.60.0") == stamp
    assert _cache.source_stamp(tmp_path, "0.61.0") != stamp
    (tmp_path / "b.py").write_text("y = 3\n")
    assert _cache.source_stamp(tmp_path, "0.60.0") != stamp


def test_invalidate_deletes_only_this_package_entries(tmp_path):
    tag = f"py{sys.version_info[0]}{sys.version_info[1]}{getattr(sys, 'abiflags', '')}"
    ours = [f"frames.log3-22.{tag}.nbi", f"frames.log3-22.{tag}.1.nbc", f"tick.run_program-62.{tag}.nbi",
            "tick.run_program-62.py399.nbi"]  # another Python's entry is as stale
    others = ["frames.cpython-311.pyc", "other.f-3.py311.nbi"]
    for name in ours + others:
        (tmp_path / name).write_bytes(b"")
    modules = ("frames", "tick")
    assert not _cache.is_cold(tmp_path, modules)
    assert not _cache.is_cold(tmp_path, ("frames",))
    assert _cache.is_cold(tmp_path, ("frames", "joints"))  # joints has no index: it will compile
    assert _cache.invalidate(tmp_path, "stamp 1", modules)  # no record yet: compiled from unknown sources
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(others + [_cache.STAMP_FILE])
    assert _cache.is_cold(tmp_path, modules)
    for name in ours:
        (tmp_path / name).write_bytes(b"")
    assert not _cache.invalidate(tmp_path, "stamp 1", modules)  # same sources: kept
    assert all((tmp_path / name).exists() for name in ours)
    assert _cache.invalidate(tmp_path, "stamp 2", modules)
    assert not any((tmp_path / name).exists() for name in ours)


def test_cache_directory_is_numbas(warm):
    """The directory the rule watches is the one numba writes the kernels' entries to."""
    import numba

    folder = Path(kernels.__file__).parent
    directory = _cache.cache_dir(folder / "frames.py")
    assert directory == kernels.cache_directory == _cache.default_cache_dir(folder / "frames.py")
    assert (directory / _cache.STAMP_FILE).read_text().strip() == _cache.source_stamp(folder, numba.__version__)
    assert not _cache.is_cold(directory, tuple(kernels.COMPILED))


_CALLEE = """
from numba import njit

@njit("float64(float64)", cache=True)
def g(x):
    return x + 1.0
"""
_CALLER = """
from numba import njit
from .callee import g

@njit("float64(float64)", cache=True)
def f(x):
    return g(x) * 10.0
"""
_INIT = """
import importlib.util
from pathlib import Path

spec = importlib.util.spec_from_file_location("kernel_cache", {cache_module!r})
cache = importlib.util.module_from_spec(spec)
spec.loader.exec_module(cache)
cache.prepare(Path(__file__).parent, ("callee", "caller"))
"""


@pytest.mark.slow  # three subprocesses compiling with numba: ~10 s
@pytest.mark.parametrize("where", ["in-tree", "NUMBA_CACHE_DIR", "user-wide"])
def test_changed_callee_in_another_file_is_recompiled(tmp_path, where):
    """A caller cached by numba keeps a changed callee of another file (numba alone would load
    ``f(1) = 20`` after ``g`` became ``x + 2``); the rule deletes the entries and says so."""
    package = tmp_path / "pkg"
    package.mkdir()
    (package / "__init__.py").write_text(_INIT.format(cache_module=_cache.__file__))
    (package / "callee.py").write_text(_CALLEE)
    (package / "caller.py").write_text(_CALLER)
    env = {"PYTHONPATH": str(tmp_path)}
    if where == "NUMBA_CACHE_DIR":
        env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba-cache")
    elif where == "user-wide":  # where numba caches for a read-only site-packages
        env |= {"NUMBA_CACHE_LOCATOR_CLASSES": "UserWideCacheLocator", "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    run = "from pkg.caller import f; print(f(1.0))"

    first = _python(run, env, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    assert (first.stdout.strip(), first.stderr.strip()) == ("20.0", _cache.COLD_MESSAGE)
    again = _python(run, env, cwd=tmp_path)
    assert (again.stdout.strip(), again.stderr) == ("20.0", "")  # loaded from the cache, silently
    if where != "in-tree":
        assert not (package / "__pycache__").exists() or not list((package / "__pycache__").glob("*.nbi"))

    (package / "callee.py").write_text(_CALLEE.replace("x + 1.0", "x + 2.0"))
    changed = _python(run, env, cwd=tmp_path)
    assert changed.returncode == 0, changed.stderr
    assert (changed.stdout.strip(), changed.stderr.strip()) == ("30.0", _cache.CHANGED_MESSAGE)


def test_an_op_compiles_after_its_generated_file_was_replaced(tmp_path):
    """Another wbc version sharing the cache directory replaces the generated callbacks file
    (its own sources): an op first added afterwards still compiles (was numba's 'cannot cache
    function ... no locator' RuntimeError), and the file is written again."""
    result = _python("""
        import glob, os
        from wbc.runtime import kernels
        kernels.callback(kernels.HAS_NAN)
        generated = glob.glob(os.path.join(str(kernels.cache_directory), "wbc_tick_ops_*.py"))
        for path in generated:
            os.remove(path)
        kernels.callback(kernels.POSTURE)
        print(len(generated), all(os.path.isfile(path) for path in generated))
    """, {"NUMBA_CACHE_DIR": str(tmp_path / "cache")})
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["1", "True"]
