"""Compiled (numba) kernels of the control tick, loaded on first use.

In CPython every numpy call on a small array costs 0.25-1 us, whatever it computes; the
QP of one youBot tick needs ~40 of them. The kernels do the arithmetic of the hottest
tasks and constraints, and of the QP assembly, in one native call each (~0.2 us to
enter). Pinocchio still computes the kinematics: the kernels read its joint placements
and joint Jacobians in place (see :class:`wbc.model.kinematics.Kinematics`).

This package module holds only pure Python: the layouts the kernels share with the tasks
(``FRAME_*``, ``POSITION_*``, ``POSE_*``), the opcodes of the tick program (``OP_*``) and
``GRAM_CONDITION``. The kernels themselves live in topic modules -- :mod:`.frames` (SO(3),
pose check, frame Jacobian, FrameTask / PositionTask rows), :mod:`.joints` (posture,
steering, position-limit and heading rows), :mod:`.manipulability`, :mod:`.assembly`
(normal equations, preview solve, bound clip, cost normalisation, NaN screen, answer
check), :mod:`.hierarchy` (the levels of strict priorities) and :mod:`.tick` (the
program interpreter) -- imported by :func:`load` on the first access of a
compiled function (``kernels.run_program``; :class:`~wbc.model.kinematics.Kinematics`
calls :func:`load`, so building a controller does), never by ``import wbc``. :func:`load`
binds every compiled function into this namespace, so later ``kernels.x`` lookups are
plain attribute hits (the module ``__getattr__`` runs only before the first load).

Each kernel has one explicit signature, so it compiles when its module is imported --
never inside a control tick -- and is cached on disk (``cache=CACHE``): only the first load
after an install pays the compilation (~20 s, announced by one line on stderr; ``wbc
warmup`` pays it up front); later loads read the machine code (~0.3 s). Where numba finds no
writable cache directory (a read-only install and a read-only home: ``NUMBA_CACHE_DIR``
unset, the package's ``__pycache__`` and the user cache not writable), ``CACHE`` is False:
the kernels compile in memory at every load, said once on stderr with the fix
(``wbc.runtime.kernels._cache.NO_CACHE_MESSAGE``).

**Cache rule.** numba keys a cached function on its *own* source file only: a callee in
another topic module, or a constant of this file, is compiled into the caller's machine
code without taking part in the key, so editing it would leave the caller's cached code
stale (tested). Before any topic module compiles, :func:`prepare_cache` therefore hashes
every ``*.py`` file of this package (and the numba version), compares the hash with the
one recorded in numba's cache directory for the package (:func:`wbc.runtime.kernels._cache.cache_dir`)
and, when they differ, deletes all of the package's cache entries: a change to any kernel
file recompiles every kernel. Kernel code belongs in this package only (a jitted function
elsewhere that calls these kernels is not covered by the rule).

Conventions: as in :mod:`wbc.model.robot` -- world-aligned axes, twists (linear; angular),
rotation matrices row-major 3x3.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

# ------------------------------------------------------------- validation

#: results of :func:`pose_defect`
POSE_OK, POSE_NOT_FINITE, POSE_LAST_ROW, POSE_NOT_ROTATION = range(4)

# ------------------------------------------------------------------- tasks

#: layout of the FrameTask settings vector (owned by the task, shared by its controllers)
FRAME_TARGET_ROTATION = slice(0, 9)  # target orientation R* (row-major)
FRAME_TARGET_POSITION = slice(9, 12)  # target position p* [m]
FRAME_WEIGHTS = slice(12, 18)  # W = sqrt(cost), (linear; angular)
FRAME_WEIGHTED_FEEDFORWARD = slice(18, 24)  # W xi* (zero without feed-forward)
FRAME_GAIN, FRAME_MAX_SPEED, FRAME_MAX_ANGULAR_SPEED = 24, 25, 26  # gain in (0, 1], [m/s], [rad/s]
FRAME_SETTINGS = 27
#: layout of a frame's placement data (one vector per controller and frame, see frame_in_joint)
FRAME_LOCAL = slice(0, 12)  # frame placement in its parent joint: rotation (row-major), translation [m]
FRAME_DATA = 24  # 12:24 is the kernels' scratch (R* R^T, then the frame origin)

#: layout of the PositionTask settings vector (owned by the task, shared by its controllers)
POSITION_TARGET = slice(0, 3)  # p* [m]
POSITION_WEIGHTS = slice(3, 6)  # W = sqrt(cost)
POSITION_FEEDFORWARD = slice(6, 9)  # pdot* [m/s]
POSITION_GAIN, POSITION_MAX_SPEED = 9, 10  # gain in (0, 1], [m/s]
POSITION_SETTINGS = 11

# ---------------------------------------------------------- manipulability

#: closed form accepted while det(gram) > GRAM_CONDITION * (mean eigenvalue)^size
GRAM_CONDITION = 1e-8

# ------------------------------------------------------------- tick program

#: opcodes of the tick program (:func:`run_program`)
(OP_FRAME_TASK, OP_POSTURE, OP_POSITION_LIMITS, OP_NORMAL_EQUATIONS, OP_MERGE_BOUNDS, OP_HAS_NAN, OP_HEADING_ROWS,
 OP_MANIPULABILITY_BARRIER, OP_POSITION_TASK, OP_PREVIEW, OP_STEERING, OP_NORMALISE_COST, OP_DAQP_SOLVE,
 OP_LIFT) = range(1, 15)
#: a third-party op (wbc.runtime.compiled_op.CompiledOp): row [OP_EXTERNAL, callback address, operands...]
OP_EXTERNAL = 100
#: forward kinematics of a chain of 1-DOF joints (wbc.model.kinematics' native mode)
OP_FORWARD_KINEMATICS = 15
#: strict task priorities (wbc.control.hierarchy, kernels in .hierarchy)
OP_LEVEL_CONSTRAINTS, OP_NORMALISE_LEVEL, OP_BAND, OP_HIERARCHY_PREVIEW = range(16, 20)
#: the optimality certificate of a lifted QP's answer (wbc.qp.lifting)
OP_LIFT_CHECK = 20
#: the error-scaled (Levenberg-Marquardt) damping of the tasks (Controller.lm_damping): each task's
#: mu summed per level, then written into the damping rows of one weighted level, or added to the
#: Hessian of one level of a hierarchy
OP_LM_TASK, OP_LM_DAMPING_ROWS, OP_LM_DAMPING_LEVEL = 21, 22, 23

# ------------------------------------------------------------------ chains

#: columns of a joint's row in the chain description (:func:`forward_kinematics`): parent, kind,
#: q index, v index, axis (3), placement in the parent: rotation row-major (9), translation (3)
CHAIN_COLUMNS = 19
CHAIN_REVOLUTE, CHAIN_PRISMATIC = 0.0, 1.0

# ------------------------------------------------------------ native DAQP

#: float64 words of DAQP's C structures (checked against wbc.solvers.daqp.abi's ctypes layouts by its probe)
DAQP_PROBLEM_WORDS, DAQP_WORKSPACE_WORDS, DAQP_RESULT_WORDS = 10, 41, 8
#: int32 indices of DAQPResult's exitflag and iter (checked likewise)
DAQP_RESULT_EXITFLAG, DAQP_RESULT_ITERATIONS = 8, 9
#: layout of the control vector of the compiled DAQP solve (wbc.solvers.daqp.native): the update mask
#: of this tick in; the exit flag, the answer's defect (qp_defect; inf for a non-finite
#: answer), the solve time [s] and DAQP's iterations out
DAQP_CONTROL_MASK, DAQP_CONTROL_EXITFLAG, DAQP_CONTROL_DEFECT, DAQP_CONTROL_TIME, DAQP_CONTROL_ITERATIONS = range(5)
DAQP_CONTROL_SIZE = 5
#: (exit flag, defect, solve time [s]) of the control vector, read in one slice
DAQP_CONTROL_OUTCOME = slice(DAQP_CONTROL_EXITFLAG, DAQP_CONTROL_TIME + 1)
#: exit flag of a solve that a NaN screen earlier in the program skipped
DAQP_SKIPPED = 0

# ------------------------------------------------------- compiled functions

#: the compiled functions of each topic module, re-exported here by :func:`load`
COMPILED = {
    "frames": ("log3", "pose_defect", "frame_jacobian", "set_frame_target", "frame_task_rows",
               "position_task_rows"),
    "joints": ("posture_rows", "steering_row", "position_limit_bounds", "heading_rows"),
    "manipulability": ("manipulability_gradient", "barrier_row"),
    "assembly": ("normal_equations", "lm_curvature", "lm_damping_rows", "lm_damping_level", "preview_solve",
                 "merge_bounds", "normalise_cost", "constraint_defect", "qp_defect", "has_nan", "has_non_finite",
                 "lift_qp", "lifted_stationarity"),
    "native_qp": ("daqp_solve",),
    "chain": ("forward_kinematics",),
    "hierarchy": ("level_constraints", "normalise_level", "band_rows", "hierarchy_preview"),
    "tick": ("run_program",),
}
_MODULE_OF = {name: module for module, names in COMPILED.items() for name in names}

_prepared = False
_loaded = False
#: numba's cache directory of this package, known after the first :func:`prepare_cache`
#: (None: numba found no writable place and compiles on every load)
cache_directory: Path | None = None


def prepare_cache() -> bool:
    """Apply the cache rule of this package's docstring once per process, before the first
    topic module compiles (each topic module calls it first and passes the result as numba's
    ``cache``): stale entries are deleted, a cold cache is announced by one line on stderr, and
    so is the lack of a writable cache directory. Returns whether the kernels can be cached."""
    global _prepared, cache_directory
    if not _prepared:
        from . import _cache

        cache_directory = _cache.prepare(Path(__file__).parent, tuple(COMPILED))
        _prepared = True
    return cache_directory is not None


def load() -> None:
    """Import (compile or load from the cache) every kernel and bind it into this namespace."""
    global _loaded
    if _loaded:
        return
    prepare_cache()
    namespace = globals()
    for module_name, names in COMPILED.items():
        module = importlib.import_module(f"{__name__}.{module_name}")
        for name in names:
            namespace[name] = getattr(module, name)
    _loaded = True


def __getattr__(name: str) -> Any:
    """A compiled function, loading the kernels on first access (PEP 562)."""
    if name in _MODULE_OF:
        load()
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_MODULE_OF))
