"""Compiled (numba) kernels of the control tick, loaded on first use.

In CPython every numpy call on a small array costs 0.25-1 us, whatever it computes; the
QP of one youBot tick needs ~40 of them. The kernels do the arithmetic of the hottest
tasks and constraints, and of the QP assembly, in one native call each (~0.2 us to
enter). Pinocchio still computes the kinematics: the kernels read its joint placements
and joint Jacobians in place (see :class:`wbc.model.kinematics.Kinematics`).

This package module holds only pure Python: the layouts the kernels share with the tasks
(``FRAME_*``, ``POSITION_*``, ``POSE_*``) and ``GRAM_CONDITION``. The kernels themselves
live in topic modules -- :mod:`.frames` (SO(3), pose check, frame Jacobian, FrameTask /
PositionTask rows), :mod:`.joints` (posture, steering, position-limit and heading rows),
:mod:`.manipulability`, :mod:`.assembly` (normal equations, preview solve, bound clip, cost
normalisation, NaN screen, answer check), :mod:`.hierarchy` (the levels of strict
priorities), ... -- each with the declarations of its tick-program ops (:class:`.ops.Op`:
operands, checks, kernel; every ``*.py`` file of this package not starting with ``_`` is a
topic module). :func:`load` imports them on the first access of an op or a compiled function
(``kernels.FRAME_TASK``, ``kernels.run_program``; :class:`~wbc.model.kinematics.Kinematics` calls
:func:`load`, so building a controller does), never ``import wbc``; it numbers the ops and binds
them into this namespace.

**When the kernels compile.** Only what a controller uses, when it is built -- never inside a
control tick: a kernel compiled lazily in a tick would stall the loop for seconds. An op's C
callback (:func:`callback`: the op's kernel and the kernels it calls) compiles when a program first
adds the op; a compiled function (``kernels.posture_rows``, declared with its signature:
:mod:`._lazy`) compiles when first fetched here, which the objects calling it in ticks do when
they are built (:func:`prepare`; items computed in Python list theirs in ``python_kernels``).
Importing a kernel module compiles nothing; the interpreter ``run_program`` (:mod:`.tick`), which
every program needs, is a compiled function prepared when a program is made
(``tests/test_no_compile_in_ticks.py`` checks that no tick compiles). Everything compiled is
cached on disk (``cache=CACHE``): after an install the first start of a controller compiles its
own kernels once (a few seconds, announced by one line on stderr; ``wbc warmup`` compiles all of
them up front, with the collision package's, ~45 s); later starts read the machine code. On that
first start, where a core is idle, worker processes compile part of them into the cache in
parallel while the controller is built (:func:`batch`, :mod:`._pool`; ``WBC_COMPILE_WORKERS``
sets their number): one starts at
``import wbc`` already, on the kernels every controller uses (:func:`start_compiling`), and is
kept at the first build where its core was otherwise idle. Where numba finds no writable cache
directory (a read-only install and a read-only home: ``NUMBA_CACHE_DIR`` unset, the package's
``__pycache__`` and the user cache not writable), ``CACHE`` is False: the kernels compile in
memory at every start, said once on stderr with the fix
(``wbc.runtime.kernels._cache.NO_CACHE_MESSAGE``).

**Cache rule.** numba keys a cached function on its *own* source file only: a callee in
another topic module, or a constant of this file, is compiled into the caller's machine
code without taking part in the key, so editing it would leave the caller's cached code
stale (tested). Before any topic module compiles, :func:`prepare_cache` therefore hashes
every ``*.py`` file of this package (and the numba version), compares the hash with the
one recorded in numba's cache directory for the package (:func:`wbc.runtime.kernels._cache.cache_dir`)
and, when they differ, deletes all of the package's cache entries: a change to any kernel
file recompiles every kernel. The generated op callbacks are a file named by the hash of its
source, which holds that stamp: a changed kernel file gives a new file, compiled afresh
(:func:`.tick.callbacks`). Kernel code belongs in this package only (a jitted function
elsewhere that calls these kernels is not covered by the rule).

Conventions: as in :mod:`wbc.model.robot` -- world-aligned axes, twists (linear; angular),
rotation matrices row-major 3x3.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import os
import pkgutil
import sys
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

from . import _pool  # (imported now: its import starts the window over which _pool.worker_count measures idle cores)

if TYPE_CHECKING:  # pragma: no cover
    from collections.abc import Callable, Iterator

    from ._pool import CompilePool
    from .ops import Op

# ------------------------------------------------------------- validation

#: results of :func:`pose_defect` (and POSE_SHAPE: not 4 x 4, from :func:`set_frame_pose`)
POSE_OK, POSE_NOT_FINITE, POSE_LAST_ROW, POSE_NOT_ROTATION, POSE_SHAPE = range(5)
#: max ``|R^T R - I|`` and ``|det R - 1|`` accepted for a rotation (``wbc.core.validation``'s, and
#: :func:`set_frame_pose`'s built in: one argument fewer for the control loop's ``set_target``)
ROTATION_TOLERANCE = 1e-6

# ------------------------------------------------------------------- tasks

#: layout of the FrameTask settings vector (owned by the task, shared by its controllers)
FRAME_TARGET_ROTATION = slice(0, 9)  # target orientation R* (row-major)
FRAME_TARGET_POSITION = slice(9, 12)  # target position p* [m]
FRAME_WEIGHTS = slice(12, 18)  # W = sqrt(cost), (linear; angular)
FRAME_FEEDFORWARD = slice(18, 24)  # xi* [m/s, rad/s] (zero without feed-forward; weighted at tick time)
FRAME_GAIN, FRAME_MAX_SPEED, FRAME_MAX_ANGULAR_SPEED = 24, 25, 26  # gain in (0, 1], [m/s], [rad/s]
FRAME_HAS_TARGET = 27  # 1.0 once the setters wrote a target (read before the first tick, never in one)
FRAME_SETTINGS = 28
#: layout of a frame's placement data (one vector per controller and frame, see frame_in_joint)
FRAME_LOCAL = slice(0, 12)  # frame placement in its parent joint: rotation (row-major), translation [m]
FRAME_LOCAL_ROTATION = slice(0, 9)  # its rotation part
FRAME_RELATIVE = slice(12, 21)  # kernels' scratch: R* R^T (row-major)
FRAME_ORIGIN = slice(21, 24)  # kernels' scratch: the frame origin in the world [m]
FRAME_DATA = 24

#: layout of the PositionTask settings vector (owned by the task, shared by its controllers)
POSITION_TARGET = slice(0, 3)  # p* [m]
POSITION_WEIGHTS = slice(3, 6)  # W = sqrt(cost)
POSITION_FEEDFORWARD = slice(6, 9)  # pdot* [m/s]
POSITION_GAIN, POSITION_MAX_SPEED = 9, 10  # gain in (0, 1], [m/s]
POSITION_SETTINGS = 11
#: layout of the PostureTask settings vector
POSTURE_GAIN = 0  # gain in (0, 1]
POSTURE_SETTINGS = 1
#: layout of the SteeringTask settings vector
STEERING_WEIGHT, STEERING_GAIN, STEERING_SPEED_SCALE = 0, 1, 2  # sqrt(cost), gain in (0, 1], [m/s]
STEERING_SETTINGS = 3

# ------------------------------------------------------------ constraints

#: layout of the ManipulabilityBarrier settings vector
BARRIER_GAIN, BARRIER_MIN_VALUE = 0, 1  # gain in (0, 1], m_min > 0
BARRIER_SETTINGS = 2

#: layout of the ``base`` indices of the AccelerationLimits kernel (acceleration_bounds): the velocity
#: indices of the base's x, y and heading rate, the channel of the heading rate (BASE_X < 0: no base channels)
BASE_X, BASE_Y, BASE_YAW, BASE_YAW_CHANNEL = range(4)
BASE_SIZE = 4

# ---------------------------------------------------------- manipulability

#: closed form accepted while det(gram) > GRAM_CONDITION * (mean eigenvalue)^size
GRAM_CONDITION = 1e-8

# ------------------------------------------------------------------ chains

#: columns of a joint's row in the chain description (:func:`forward_kinematics`): parent, kind,
#: q index, v index, axis (3), placement in the parent: rotation row-major (9), translation (3)
CHAIN_COLUMNS = 19
CHAIN_REVOLUTE, CHAIN_PRISMATIC = 0.0, 1.0

# ------------------------------------------------------------ native DAQP

#: float64 words of DAQP's C structures (checked against wbc.solvers.daqp.abi's ctypes layouts by its probe)
DAQP_PROBLEM_WORDS, DAQP_WORKSPACE_WORDS, DAQP_RESULT_WORDS = 10, 41, 8
#: float64 words of DAQPSettings and the word of its primal_tol (checked likewise)
DAQP_SETTINGS_WORDS, DAQP_SETTINGS_PRIMAL_TOL = 17, 0
#: int32 indices of DAQPResult's exitflag and iter (checked likewise)
DAQP_RESULT_EXITFLAG, DAQP_RESULT_ITERATIONS = 8, 9
#: int32 index of DAQPProblem's m, word of its A (bupper and blower the next two), int32 index of
#: DAQPWorkspace's m, word of its sense (checked likewise; the packing of wbc.runtime.kernels._inert_rows)
DAQP_PROBLEM_M, DAQP_PROBLEM_A, DAQP_WORKSPACE_M, DAQP_WORKSPACE_SENSE = 1, 4, 3, 8
#: layout of the control vector of the compiled DAQP solve (wbc.solvers.daqp.native): the update mask
#: of this tick in; the exit flag, the answer's defect (qp_defect; inf for a non-finite
#: answer), the solve time [s] and DAQP's iterations out; the solve time of the latest answer that
#: a DAQP_ACCEPT op accepted (what the controller's native tick records)
(DAQP_CONTROL_MASK, DAQP_CONTROL_EXITFLAG, DAQP_CONTROL_DEFECT, DAQP_CONTROL_TIME, DAQP_CONTROL_ITERATIONS,
 DAQP_CONTROL_ACCEPTED_TIME) = range(6)
DAQP_CONTROL_SIZE = 6
#: (exit flag, defect, solve time [s]) of the control vector, read in one slice
DAQP_CONTROL_OUTCOME = slice(DAQP_CONTROL_EXITFLAG, DAQP_CONTROL_TIME + 1)
#: exit flag of a solve that a NaN screen earlier in the program skipped
DAQP_SKIPPED = 0
#: DAQP's exit flag of an optimal answer (EXIT_OPTIMAL), also the unconstrained minimiser's (native_qp.daqp_solve)
DAQP_OPTIMAL = 1
#: bits of DAQP's constraint states: active, at its lower side, immutable (an equality row)
#: (DAQP's ACTIVE, LOWER, IMMUTABLE; its other bits mark soft and binary constraints and its own use)
DAQP_SENSE_ACTIVE, DAQP_SENSE_LOWER, DAQP_SENSE_IMMUTABLE = 1, 2, 4
#: DAQP's soft bit, and its own mark of a zero row it was given (constants.h DAQP_SOFT, DAQP_ZERO_ROW)
DAQP_SENSE_SOFT, DAQP_SENSE_ZERO_ROW = 8, 2048

# ------------------------------------------------------- compiled functions

#: the compiled functions of each topic module, re-exported here by :func:`load`
COMPILED = {
    "frames": ("log3", "pose_defect", "frame_jacobian", "set_frame_pose",
               "frame_task_rows",
               "position_task_rows"),
    "joints": ("integrate_vector_space", "posture_rows", "steering_row", "position_limit_bounds", "heading_rows"),
    "manipulability": ("manipulability_gradient", "barrier_row"),
    "assembly": ("normal_equations", "lm_curvature", "lm_damping_rows", "lm_damping_level", "preview_solve",
                 "merge_bounds", "normalise_cost", "constraint_defect", "qp_defect", "leading_defect", "has_nan",
                 "has_non_finite", "lift_qp", "lifted_stationarity", "cholesky", "forward_substitution",
                 "back_substitution"),
    "native_qp": ("daqp_solve", "daqp_solve_working_set"),
    "chain": ("forward_kinematics",),
    "hierarchy": ("level_constraints", "normalise_level", "band_rows", "hierarchy_preview"),
    "acceleration": ("braking_speed", "acceleration_bounds"),
    "tick": ("run_program",),
}
_MODULE_OF = {name: module for module, names in COMPILED.items() for name in names}

_prepared = False
_loaded = False
_stamp = ""  #: the package's source stamp (set by :func:`load`), in the generated callbacks' header
_ops: list[Op] = []  #: every declared op, by name (set by :func:`load`)
_callbacks: dict[str, Any] = {}  #: the compiled callback of each op used in this process, by name
_callback_module: ModuleType | None = None  #: the generated module of the callbacks (:mod:`.tick`)
#: numba's cache directory of this package, known after the first :func:`prepare_cache`
#: (None: numba found no writable place and compiles on every load)
cache_directory: Path | None = None
_cold = False  #: the interpreter had no cache entry at the first :func:`prepare_cache` (a first start)
_workers: CompilePool | None = None  #: the compile workers of a first start (:func:`_compile_pool`)
_workers_started = False
_early = False  #: the workers were started at import, not yet kept (:func:`start_compiling`)
_batch_depth = 0  #: open :func:`batch` blocks
_queued: dict[str, Callable[[], object]] = {}  #: jobs queued for the workers: how to compile each here


def topic_modules() -> tuple[str, ...]:
    """The modules of this package (every ``*.py`` file not starting with ``_``), sorted."""
    return tuple(sorted(module.name for module in pkgutil.iter_modules(__path__) if not module.name.startswith("_")))


def prepare_cache() -> bool:
    """Apply the cache rule of this package's docstring once per process, before the first
    topic module compiles (each topic module calls it first and passes the result as numba's
    ``cache``): stale entries are deleted, a cold cache is announced by one line on stderr, and
    so is the lack of a writable cache directory. Returns whether the kernels can be cached."""
    global _prepared, _cold, cache_directory
    if not _prepared:
        from . import _cache

        # cold: the interpreter, which every program needs, has no cache entry (the other kernels
        # compile when a controller first uses them)
        cache_directory = _cache.prepare(Path(__file__).parent, topic_modules(), cold=("tick",))
        _cold = cache_directory is not None and _cache.is_cold(cache_directory, ("tick",))
        _prepared = True
    return cache_directory is not None


def load() -> None:
    """Import every kernel module (nothing is compiled), and bind its declared ops
    (:class:`.ops.Op`, numbered 1, 2, ... by name) into this namespace."""
    global _loaded, _stamp
    if _loaded:
        return
    prepare_cache()
    import numba

    from . import _cache
    from .ops import Op

    namespace = globals()
    declared: dict[str, Op] = {}
    for module_name in topic_modules():
        module = importlib.import_module(f"{__name__}.{module_name}")
        for name, value in vars(module).items():
            if not isinstance(value, Op) or declared.get(name) is value:  # not an op, or imported from another module
                continue
            if value.spec.name != name or name in declared or name in namespace or name in _MODULE_OF:
                raise TypeError(f"op {value.spec.name} ({module.__name__}.{name}): an op is declared once, as the "
                                f"module attribute of its own name, unique among the ops and names of {__name__}")
            declared[name] = value
    ops = [declared[name] for name in sorted(declared)]
    for op in ops:  # the generated callbacks import each kernel by its module and name
        kernel = getattr(op.kernel, "py_func", None)
        if kernel is None or getattr(sys.modules[kernel.__module__], kernel.__name__, None) is not op.kernel:
            raise TypeError(f"op {op.spec.name}: its kernel must be an @njit function defined at module level in "
                            f"a module of {__name__}")
    for code, op in enumerate(ops, start=1):
        op.code = code
    _ops[:] = ops
    _stamp = _cache.source_stamp(Path(__file__).parent, numba.__version__)
    namespace.update(declared)
    _loaded = True


def callback(op: Op) -> int:
    """The address of ``op``'s C callback (:mod:`.tick`), compiled -- or read from numba's cache --
    on the first call for the op in this process: when a program first adds it."""
    global _callback_module
    load()
    compiled = _callbacks.get(op.spec.name)
    if compiled is None:
        _claim(f"op {op.spec.name}")
        compiled = _callbacks.get(op.spec.name)  # (compiled meanwhile: a job compiled while waiting)
    if compiled is None:
        from numba import cfunc

        from ._lazy import compile_callees
        from .tick import BUILTIN_SIGNATURE, callbacks

        compile_callees(op.kernel)
        source = getattr(_callback_module, "__file__", None)
        if _callback_module is None or (source is not None and not Path(source).is_file()):
            # (again when another wbc version sharing the cache directory replaced the generated file)
            _callback_module = callbacks(_ops, _stamp, cache_directory)
        function = getattr(_callback_module, f"op_{op.spec.name}")
        try:
            cache = getattr(_callback_module, "__file__", None) is not None  # not when built in memory
            compiled = cfunc(BUILTIN_SIGNATURE, cache=cache)(function)
        except RuntimeError:  # numba cannot cache it (the file went away meanwhile): in memory
            compiled = cfunc(BUILTIN_SIGNATURE)(function)
        _callbacks[op.spec.name] = compiled
    return int(compiled.address)


def prepare(*names: str) -> None:
    """Compile (or read from numba's cache) the compiled functions ``names`` now: the objects of a
    controller that call them in its ticks do so when they are built (:mod:`._lazy`). While a
    controller is built (:func:`batch`) on a first start with compile workers (:mod:`._pool`), they
    are queued for the workers instead: compiled by the end of the build, or when fetched before."""
    missing = [name for name in names if name not in globals()]
    if missing and _batch_depth and _compile_pool() is not None:
        _queue({f"kernel {name}": functools.partial(prepare_one, name) for name in missing})
        return
    for name in missing:
        prepare_one(name)


@contextlib.contextmanager
def batch() -> Iterator[None]:
    """While a controller is built: on a first start with compile workers (:mod:`._pool`), the
    compiled functions it prepares and the ops its programs add are queued for the workers, and
    compiled -- here or by them, in parallel -- when the outermost batch ends (:func:`settle`; a
    program's before it first runs). Elsewhere, and without workers, nothing changes."""
    global _batch_depth
    _batch_depth += 1
    _compile_pool()  # (started now: a worker takes ~1 s to start, see _pool)
    try:
        yield
    finally:
        _batch_depth -= 1
    if not _batch_depth:
        settle()


def prepare_one(name: str) -> None:
    """Compile (or read from numba's cache) the compiled function ``name`` in this process."""
    if name not in globals():
        __getattr__(name)


def submit(op: Op) -> bool:
    """In a :func:`batch` on a first start with compile workers (:mod:`._pool`): queue ``op``'s callback for them and
    return True -- the program fetches it with :func:`callback` after :func:`settle`, before it
    first runs; else False (nothing done: compile it with :func:`callback`)."""
    if op.spec.name in _callbacks or not _batch_depth or _compile_pool() is None:
        return False
    _queue({f"op {op.spec.name}": functools.partial(callback, op)})
    return True


def settle() -> None:
    """Compile everything queued for the compile workers (:func:`prepare`, :func:`submit`) now (see
    :func:`_settle`): the end of a :func:`batch`."""
    _settle(list(_queued))


def callbacks(ops: list[Op]) -> list[int]:
    """The callback addresses of ``ops`` (:func:`callback`), those queued for the compile workers
    settled first (:func:`_settle`): a program's, before it first runs."""
    _settle([f"op {op.spec.name}" for op in ops])
    return [callback(op) for op in ops]


def _settle(jobs: list[str]) -> None:
    """Compile the queued ``jobs``: here those no worker has started (earliest first), then read
    those the workers compiled from numba's cache (waiting for those still running: :func:`_claim`;
    compiling here those a worker failed)."""
    steps = [(job, _queued.pop(job)) for job in jobs if job in _queued]
    for job, compile_here in steps:
        if _workers is not None and _workers.take(job):
            compile_here()
    for _, compile_here in steps:
        compile_here()


def _queue(jobs: dict[str, Callable[[], object]]) -> None:
    """Queue ``jobs`` (job name: how to compile it here) for the compile workers."""
    _queued.update(jobs)
    assert _workers is not None
    _workers.submit(list(jobs))


def _claim(job: str) -> None:
    """Before compiling ``job`` here: take it from the compile workers' queue, or wait while a worker
    compiles it (numba then reads it from the cache) -- compiling meanwhile here the earliest jobs
    no worker has started (the build needs ``job`` now, e.g. DAQP's solve for its layout probe:
    the process would otherwise idle for seconds)."""
    if _workers is None or _workers.take(job):
        return
    while _workers.running(job):
        other = _workers.take_oldest()
        if other is None:
            break
        try:
            _compile_job(other)
        except Exception:  # noqa: BLE001 - not this build's job: compiled again, and raising, where it is needed
            pass
    _workers.wait(job)


def _compile_job(job: str) -> None:
    """Compile the job ``job`` (``"op NAME"``: an op's callback; ``"kernel name"``: a compiled
    function) in this process (also a worker's, :mod:`._worker`); raises for a job of neither kind."""
    kind, name = job.split()
    if kind == "op":
        callback(globals()[name])
    elif kind == "kernel":
        prepare_one(name)
    else:
        raise ValueError(f"not a compile job: {job!r}")


def _claim_declared(dispatcher: Any) -> None:
    """:func:`_claim` for a compiled function about to compile (also as the callee of another)."""
    name = getattr(getattr(dispatcher, "py_func", None), "__name__", "")
    if name in _MODULE_OF:
        _claim(f"kernel {name}")


def _compile_pool() -> CompilePool | None:
    """The compile workers (:mod:`._pool`), started on the first call of a first start (a cold
    cache that numba can write); None otherwise, or with ``WBC_COMPILE_WORKERS=0``. Workers started
    at ``import wbc`` (:func:`start_compiling`) are kept on the first call after it only where the
    cores they use were idle otherwise (:func:`._pool.worker_count` of the other processes)."""
    global _workers, _workers_started, _early
    if not _workers_started:
        _workers_started = True
        prepare_cache()  # (whether the cache is cold; the workers start before load() imports the kernel modules)
        _start_workers(_pool.worker_count() if _cold else 0)
    elif _early:
        _early = False
        if _workers is not None and not _pool.worker_count(_workers.pids):
            _workers.close()  # the machine is busy: they would only compete with this process
            _workers = None
    if _workers is not None:
        from . import _lazy

        _lazy.before_compile = _claim_declared
    load()
    return _workers


def _forget_workers() -> None:
    """In a child forked from this process: the compile workers are the parent's (their threads
    did not follow): the child compiles on its own."""
    global _workers, _early
    _workers, _early = None, False
    lazy: Any = sys.modules.get(f"{__name__}._lazy")  # (not imported here: a fork need not import numba)
    if lazy is not None:
        lazy.before_compile = lazy._nothing_before


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_workers)


def _start_workers(count: int) -> None:
    """Start ``count`` compile workers (none: nothing)."""
    global _workers
    if count:
        try:
            _workers = _pool.CompilePool(count)
        except OSError:
            _workers = None


#: jobs that every controller compiles with the default solver (DAQP) on a robot of revolute and prismatic
#: joints: the interpreter, the NaN screens, the cost's normal equations and scaling, the merged bounds, the
#: answer checks, the chain's kinematics, DAQP's solve and acceptance -- the workers of a first start
#: take them at ``import wbc`` (:func:`start_compiling`), the last first (DAQP's solve, the longest); kept by
#: hand, each checked to be one that plain controllers use (tests/test_compile_workers.py)
COMMON_JOBS = ("kernel run_program", "op HAS_NAN", "op FORWARD_KINEMATICS", "op NORMAL_EQUATIONS",
               "op MERGE_BOUNDS", "op NORMALISE_COST", "kernel qp_defect", "kernel constraint_defect",
               "op DAQP_ACCEPT", "op DAQP_SOLVE")


def start_compiling() -> None:
    """On a first start after an install (no cache entry of the interpreter, decided without
    importing numba: :func:`._cache.first_start`): start a compile worker now -- ``import wbc``
    calls this first -- and hand it :data:`COMMON_JOBS`, which it compiles while this process
    imports the rest of wbc and builds its first controller (a worker takes ~0.5 s to start, as
    long as the import). The import is too short to tell whether a core is idle: the worker is
    kept at the first build only where it was (:func:`_compile_pool`); ``WBC_COMPILE_WORKERS``
    sets the number (then kept). A common job this process needs is read from the cache, or
    taken back while no worker has started it (:func:`_settle`); one it never needs only
    filled the cache. Elsewhere, and after the first call, nothing."""
    global _workers_started, _early
    from . import _cache

    if _workers_started or not _cache.first_start(Path(__file__).parent, "tick"):
        return
    _workers_started = True
    setting = os.environ.get(_pool.WORKERS_VARIABLE, "").strip()
    _start_workers(_pool.worker_count() if setting else min(1, _pool.usable_cores() - 1))
    _early = not setting
    if _workers is not None:
        _workers.submit(list(COMMON_JOBS))


def warm_up() -> None:
    """Compile every kernel and op callback of the package now (``wbc warmup``; on a cold cache in
    parallel with the compile workers, :mod:`._pool`)."""
    load()
    with batch():  # (its end compiles what it queued)
        prepare(*_MODULE_OF)
        for op in _ops:
            submit(op)
    for op in _ops:
        callback(op)  # (read from the cache, or compiled here without workers)


def __getattr__(name: str) -> Any:
    """A compiled function, compiled for its declared signature on first access (:mod:`._lazy`),
    or a declared op (an upper-case name), loading the kernels on first access (PEP 562)."""
    if name in _MODULE_OF:
        load()
        from ._lazy import compile_declared

        function = getattr(sys.modules[f"{__name__}.{_MODULE_OF[name]}"], name)
        compile_declared(function)
        globals()[name] = function  # later lookups are plain attribute hits
        return function
    if name.isupper() and not _loaded:
        load()
        if name in globals():
            return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_MODULE_OF))
